"""The RL baselines' views of the other agents, in place of the Group Information Fusion.

Each module has the fusion's signature ``forward(pair, groups, alive) -> (B, N, width)``
(``groups`` is ignored) and is picked by :attr:`masp_lite.config.NetConfig.executor`; the
goal and obstacle embeddings, the head and the critic around it are MASP's, so a baseline
differs from MASP only where the paper says it does.

* :class:`NearestMLP` (``executor="nearest"``, used by ``h-mappo``): an MLP over the
  ``neighbours`` nearest alive agents' pair features, nearest first — the MAPPO executor
  without Group Information Fusion (an MLP over own state, goal and nearest neighbours);
  missing neighbours (a smaller or thinned team) read as an agent at the sensing edge.
* :class:`AttentionSubgraph` (``executor="subgraph"``, used by ``mage-x``): MAGE-X's
  executor graph. Every other alive agent gets an attention score from its pair features
  (an MLP); the ``neighbours`` best-scored ones form agent ``k``'s subgraph, and one graph
  layer mixes them by the softmax of their scores:
  ``relu(W (h_k + sum_j alpha_kj h_j) / 2 + b)`` with ``h = relu(W_e x + b_e)``.
  MAGE-X selects the subgraph by attention and runs a GNN on it; the exact layer is our
  choice, kept as close to MASP's GCN as possible. The selection (``topk``) has no gradient;
  the scores of the selected agents do, through ``alpha``.

The goal-free baselines (``goal_matcher="none"``: ``mappo``, ``darl1n``) have no goal to
embed: each agent sees every landmark instead, through :class:`AttentionPool` over
:func:`landmark_features` (MAPPO with "the attention mechanism", as the
paper applies it), and the other agents through

* :class:`AttentionPool` over all alive others' pair features (``executor="attention"``,
  ``mappo``), or
* :class:`RadiusMean` (``executor="radius"``, ``darl1n``): the mean embedding of the agents
  within 1 m (the pair features' sensing radius), DARL1N's one-hop neighbourhood; its critic
  sees that view and the time left, no team-wide input (:func:`masp_lite.nets.variants.time_left_only`).

Pair features are :func:`masp_lite.nets.features.pair_features` (distance clipped at 1 m), so
"nearest" ranks the agents within 1 m by distance; beyond it they all sit at the edge and
the order among them is arbitrary but fixed (by index). Every module serves any team size.

:class:`AttentionPool` and :class:`RadiusMean` see every pair: at 50 agents a training
minibatch holds millions of (agent, other) rows. In training both run as
:class:`masp_lite.nets.kernels.PoolKernel`, a few worlds at a time with a hand-written
backward; :func:`masp_lite.nets.kernels.use_kernels` switches it off, and the two paths
agree to float rounding (tested, with ``gradcheck``).
"""
from __future__ import annotations

import torch
from torch import nn

from .encoders import mlp
from .kernels import PoolKernel

__all__ = ["NearestMLP", "AttentionSubgraph", "AttentionPool", "RadiusMean", "nearest_others", "distance_feature",
           "far", "landmark_features"]


def landmark_features(pos: torch.Tensor, vel: torch.Tensor, landmark_pos: torch.Tensor,
                      covered: torch.Tensor, max_speed: float) -> torch.Tensor:
    """(B, N, M, 2D + 3): every landmark seen from every agent, in D = 2 or 3 dimensions.

    ``[unit direction (D), min(dist, 1 m), log(1 + dist), covered, own velocity / max_speed (D)]``,
    the goal features of MASP's executor (:func:`masp_lite.nets.features.goal_features`) for each landmark, plus
    whether it is covered now.
    """
    rel = landmark_pos.unsqueeze(1) - pos.unsqueeze(2)                    # (B, N, M, D)
    d = rel.norm(dim=-1, keepdim=True)
    B, N, M, D = rel.shape
    cov = covered.to(pos.dtype).view(B, 1, M, 1).expand(B, N, M, 1)
    v = (vel / max_speed).unsqueeze(2).expand(B, N, M, D)
    return torch.cat([rel / d.clamp(min=1e-6), d.clamp(max=1.0), torch.log1p(d), cov, v], dim=-1)


def distance_feature(pair: torch.Tensor) -> torch.Tensor:
    """(...): the clipped distance of pair features ``[rel (D), min(dist, sense) / sense, dv (D), is_self]``."""
    return pair[..., (pair.shape[-1] - 2) // 2]


def far(features: int, dtype=None, device=None) -> torch.Tensor:
    """Pair features of a missing neighbour: no offset, at the sensing edge, not moving, not self."""
    out = torch.zeros(features, dtype=dtype, device=device)
    out[(features - 2) // 2] = 1.0
    return out


def nearest_others(pair: torch.Tensor, alive: torch.Tensor, count: int, key: torch.Tensor | None = None):
    """Indices (B, N, count) of each agent's ``count`` best other alive agents, and which exist.

    By default the best are the nearest (smallest clipped distance, feature 2); ``key``
    (B, N, N) ranks by it instead (smallest first). Self and dropped agents come last and
    are flagged missing in the returned mask (B, N, count).
    """
    B, N = pair.shape[:2]
    rank = distance_feature(pair) if key is None else key
    eye = torch.eye(N, dtype=torch.bool, device=pair.device)
    bad = eye.unsqueeze(0) | ~alive.unsqueeze(1)                           # [b, k, j]: j is k or dropped
    k = min(count, N)
    idx = rank.masked_fill(bad, float("inf")).topk(k, dim=-1, largest=False).indices
    ok = ~torch.gather(bad, 2, idx)
    if k < count:  # fewer agents than places: pad with missing ones
        idx = torch.cat([idx, idx.new_zeros(B, N, count - k)], -1)
        ok = torch.cat([ok, ok.new_zeros(B, N, count - k)], -1)
    return idx, ok


def _gather_pairs(pair, idx, ok):
    F = pair.shape[-1]
    rows = torch.gather(pair, 2, idx.unsqueeze(-1).expand(*idx.shape, F))
    return torch.where(ok.unsqueeze(-1), rows, far(F, pair.dtype, pair.device))


class NearestMLP(nn.Module):
    """``h-mappo``'s executor view: MLP over the ``neighbours`` nearest agents (B, N, width)."""

    def __init__(self, in_features: int = 6, width: int = 32, neighbours: int = 3):
        super().__init__()
        self.neighbours = neighbours
        self.net = mlp([neighbours * in_features, 2 * width, width], last_activation=True)

    def forward(self, pair: torch.Tensor, groups, alive: torch.Tensor) -> torch.Tensor:
        idx, ok = nearest_others(pair, alive, self.neighbours)
        rows = _gather_pairs(pair, idx, ok)                                   # (B, N, K, F)
        return self.net(rows.flatten(2))


class AttentionSubgraph(nn.Module):
    """``mage-x``'s executor view: a graph layer on the ``neighbours`` best-attended agents."""

    def __init__(self, in_features: int = 6, width: int = 32, neighbours: int = 3):
        super().__init__()
        self.neighbours = neighbours
        self.score = mlp([in_features, width, 1])
        self.embed = mlp([in_features, width], last_activation=True)
        self.gcn = nn.Linear(width, width)

    def forward(self, pair: torch.Tensor, groups, alive: torch.Tensor) -> torch.Tensor:
        B, N, _, F = pair.shape
        with torch.no_grad():  # the selection: every pair scored, no gradient through topk
            all_scores = self.score(pair).squeeze(-1)                         # (B, N, N)
        idx, ok = nearest_others(pair, alive, self.neighbours, key=-all_scores)
        rows = _gather_pairs(pair, idx, ok)                                   # (B, N, K, F)
        s = self.score(rows).squeeze(-1).masked_fill(~ok, float("-inf"))
        alpha = torch.nan_to_num(torch.softmax(s, -1), nan=0.0)               # no neighbour: all zero
        own = torch.diagonal(pair, dim1=1, dim2=2).transpose(1, 2)            # (B, N, F): k seen from k
        h_self, h = self.embed(own), self.embed(rows)
        mixed = (h_self + (alpha.unsqueeze(-1) * h).sum(2)) / 2
        return torch.relu(self.gcn(mixed))


class AttentionPool(nn.Module):
    """Attention over a set: ``forward(rows (B, N, S, F), mask (B, N, S) or None) -> (B, N, width)``.

    Each row gets a score (an MLP) and an embedding; the result is the softmax-weighted sum
    of the embeddings over the rows that exist (zeros when none does). As an executor view
    (``forward(pair, groups, alive)``) the rows are the other alive agents' pair features.
    ``kernel``: pool with :class:`masp_lite.nets.kernels.PoolKernel` when the rows need no gradient."""

    def __init__(self, in_features: int, width: int = 32, kernel: bool = True):
        super().__init__()
        self.kernel = kernel
        self.score = mlp([in_features, width, 1])
        self.embed = mlp([in_features, width], last_activation=True)

    def pool(self, rows: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        if self.kernel and not rows.requires_grad:
            first, out, embed = self.score[0], self.score[2], self.embed[0]
            return PoolKernel.apply(rows, mask, torch.cat([first.weight, embed.weight]),
                                     torch.cat([first.bias, embed.bias]), out.weight, out.bias)
        s = self.score(rows).squeeze(-1)
        if mask is not None:
            s = s.masked_fill(~mask, float("-inf"))
        alpha = torch.nan_to_num(torch.softmax(s, -1), nan=0.0)
        return (alpha.unsqueeze(-1) * self.embed(rows)).sum(-2)

    def forward(self, rows: torch.Tensor, groups=None, alive: torch.Tensor | None = None) -> torch.Tensor:
        if alive is None:  # a landmark set: every row exists
            return self.pool(rows)
        N = rows.shape[1]
        others = alive.unsqueeze(1) & ~torch.eye(N, dtype=torch.bool, device=rows.device)
        return self.pool(rows, others)


class RadiusMean(nn.Module):
    """``darl1n``'s executor view: the mean embedding of the alive agents within 1 m (B, N, width).
    ``kernel``: as :class:`AttentionPool`'s."""

    def __init__(self, in_features: int = 6, width: int = 32, kernel: bool = True):
        super().__init__()
        self.kernel = kernel
        self.embed = mlp([in_features, width], last_activation=True)

    def forward(self, pair: torch.Tensor, groups, alive: torch.Tensor) -> torch.Tensor:
        N = pair.shape[1]
        # the distance feature is min(dist, sense) / sense: below 1 means within the sensing radius, one hop
        near = (distance_feature(pair) < 1.0) & alive.unsqueeze(1) & ~torch.eye(N, dtype=torch.bool, device=pair.device)
        w = near.to(pair.dtype)
        w = w / w.sum(2, keepdim=True).clamp(min=1.0)
        if self.kernel and not pair.requires_grad:
            embed = self.embed[0]
            return PoolKernel.apply(pair, w, embed.weight, embed.bias, None, None)
        return (self.embed(pair) * w.unsqueeze(-1)).sum(2)
