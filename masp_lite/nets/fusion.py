"""Group Information Fusion (paper, section "Coordinated Action Executor").

For each agent ``k`` the other agents are split into groups, each group plus ``k`` becomes
a fully connected subgraph (edges 1), a GCN updates the nodes of every subgraph, and
``k``'s updated feature is averaged over its groups. This keeps the network's input
small (groups of ``N_g`` = 3) while every agent still hears about every other one.

:func:`group_division` — the paper's rule: agent ``k`` joins every group; the others, in a
random order, are cut into groups of ``N_g - 1``; if they do not divide evenly, agents
from the start of the random order (i.e. random agents) join a second group to fill the
last one. With fewer than ``N_g - 1`` others the single group is smaller. The random
order is one permutation per world (``perm`` (B, N)), so storing ``perm`` is enough to
rebuild the exact groups later (PPO recomputes log-probabilities from it).

:func:`gcn_layer` — Kipf & Welling's layer ``H' = ReLU(D^-1/2 (A + I) D^-1/2 H W)``. On a
fully connected subgraph with unit edges every node receives the mean of the group, so
one layer is what the paper's description supports (a second would see identical nodes);
``GroupInformationFusion(layers=...)`` still allows more.

Everything is vectorized over worlds, agents and groups. With one layer (the paper's, and
every shipped network) :class:`_OneLayerFusion` computes it a few worlds at a time so that
the training update runs from the CPU cache; the general path serves more layers and gradients
into the pair features.
Dropped agents (``alive`` False) are removed from every subgraph (no edges), and a group
whose other members are all dropped does not count in the mean.

Why hand-written: a GCN on thousands of 3-node graphs is one batched matrix product;
graph libraries (PyG) would add a heavy dependency for it.
"""
from __future__ import annotations

import math

import torch
from torch import nn

from .encoders import chunked, mlp, relu_grad

__all__ = ["group_division", "gcn_layer", "GroupInformationFusion", "random_permutation"]


CHUNK_ROWS = 20_000
"""Pair rows (agents x group members) the one-layer fusion processes at a time."""


def _linear_relu(x: torch.Tensor, weight_t: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """``relu(x @ weight_t + bias)`` for (..., F) rows: one ``addmm``, then ReLU in place."""
    return torch.addmm(bias, x.reshape(-1, x.shape[-1]), weight_t).relu_().view(*x.shape[:-1], weight_t.shape[1])


class _OneLayerFusion(torch.autograd.Function):
    """The one-layer fusion, a few worlds at a time, with a hand-written backward.

    ``apply(pair, groups, others_alive, weight, We, be, Wg, bg) -> (B, N, L)``, for pair
    features that need no gradient (they are observations): ``others_alive`` (B, N, G, n-1)
    marks the alive other members (``None``: all alive), ``weight`` (B, N, G) the groups'
    weights in the mean (rows sum to 1). Per group, ``k``'s row of one GCN layer with unit
    edges is ``relu(Wg mean(h_members) + bg)`` with ``h = relu(We x + be)``.

    Why: at 50 agents a minibatch holds millions of pair rows, and autograd keeps every
    (rows, L) intermediate: the update then runs at memory speed. Here each chunk of
    ``CHUNK_ROWS`` pair rows stays in the CPU cache, nothing but the inputs (with the row
    numbers and masks that are made from them once per call) is saved, and the backward
    recomputes a chunk's forward before its gradient (activation checkpointing); sums over
    the few members of a group are explicit additions (much faster than ``sum`` over a
    short axis), and a chunk reads its nodes with one ``index_select`` of row numbers.
    Measured on one core, 50 agents, a 720-row minibatch (best of 4): forward and backward
    2.0 s with autograd -> 0.37 s; the numbers agree with the general path
    (:func:`gcn_layer`) to float rounding (tested, with ``gradcheck``).
    """

    @staticmethod
    def _rows(groups: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Row numbers, in ``pair`` viewed as (B * N * N, F) rows, of each agent's own node (B, N) and
        of the other members of its groups (B, N, G, n - 1): one ``index_select`` then reads a
        chunk's nodes (a copy, so the same numbers as a ``gather``, at half its cost)."""
        B, N = groups.shape[:2]
        agent = torch.arange(B * N, device=groups.device).view(B, N, 1, 1) * N  # row of [b, k, 0]
        return agent[..., 0, 0] + groups[..., 0, 0], agent + groups[..., 1:]

    @staticmethod
    def _chunk(pair_rows, self_rows, other_rows, mf, count, We_t, be, Wg_t, bg):
        B, N, G, n, F = *other_rows.shape[:3], other_rows.shape[3] + 1, pair_rows.shape[1]
        x_self = pair_rows.index_select(0, self_rows.reshape(-1)).view(B, N, 1, F)
        x_oth = pair_rows.index_select(0, other_rows.reshape(-1)).view(B, N, G * (n - 1), F)
        h_self = _linear_relu(x_self, We_t, be)                               # (b, N, 1, L)
        h_oth = _linear_relu(x_oth, We_t, be).view(B, N, G, n - 1, We_t.shape[1])  # (b, N, G, n-1, L)
        total = h_self.expand(B, N, G, -1).clone() if n == 1 else None
        for i in range(n - 1):
            h_i = h_oth[:, :, :, i] if mf is None else h_oth[:, :, :, i] * mf[:, :, :, i]
            total = h_i + h_self if total is None else total.add_(h_i)
        a = total.div_(count)
        z = _linear_relu(a, Wg_t, bg)                                          # (b, N, G, L)
        return x_self, x_oth.view(B, N, G, n - 1, F), h_self, h_oth, a, z

    @staticmethod
    def _masks(others_alive, groups, dtype):
        """``(mf, count)``, made once per call: the alive other members as (B, N, G, n-1, 1) floats and
        the members counted in each group's mean (B, N, G, 1); ``(None, n)`` when all are alive."""
        if others_alive is None:
            return None, float(groups.shape[-1])
        mf = others_alive.to(dtype).unsqueeze(-1)
        return mf, mf.sum(3).add_(1.0)

    @staticmethod
    def forward(ctx, pair, groups, others_alive, weight, We, be, Wg, bg):
        B, N, G, n = groups.shape
        step = max(1, CHUNK_ROWS // (N * G * n))
        We_t, Wg_t = We.t().contiguous(), Wg.t().contiguous()
        pair_rows = pair.reshape(-1, pair.shape[-1])
        self_rows, other_rows = _OneLayerFusion._rows(groups)
        mf, count = _OneLayerFusion._masks(others_alive, groups, pair.dtype)
        out = []
        for s in range(0, B, step):
            sl = slice(s, s + step)
            z = _OneLayerFusion._chunk(pair_rows, self_rows[sl], other_rows[sl], *_slice(sl, mf, count),
                                       We_t, be, Wg_t, bg)[-1]
            out.append((z * weight[sl].unsqueeze(-1)).sum(2))
        ctx.save_for_backward(pair_rows, self_rows, other_rows, mf, weight, We, be, Wg, bg)
        ctx.step, ctx.count = step, count
        return torch.cat(out)

    @staticmethod
    def backward(ctx, grad):
        pair_rows, self_rows, other_rows, mf, weight, We, be, Wg, bg = ctx.saved_tensors
        count = ctx.count
        F, L, n = pair_rows.shape[-1], We.shape[0], other_rows.shape[-1] + 1
        We_t, Wg_t = We.t().contiguous(), Wg.t().contiguous()
        gWe, gbe, gWg, gbg = (torch.zeros_like(t) for t in (We, be, Wg, bg))
        for s in range(0, self_rows.shape[0], ctx.step):
            sl = slice(s, s + ctx.step)
            mf_s, count_s = _slice(sl, mf, count)
            x_self, x_oth, h_self, h_oth, a, z = _OneLayerFusion._chunk(pair_rows, self_rows[sl], other_rows[sl],
                                                                         mf_s, count_s, We_t, be, Wg_t, bg)
            gz = relu_grad(grad[sl].unsqueeze(2) * weight[sl].unsqueeze(-1), z, 0).view(-1, L)
            gWg += (a.view(-1, L).t() @ gz).t()
            gbg += gz.sum(0)
            g_total = (gz @ Wg).view(z.shape).div_(count_s)                   # d loss / d (sum of members)
            g_self = relu_grad(g_total.sum(2, keepdim=True), h_self, 0).view(-1, L)
            gWe += (x_self.reshape(-1, F).t() @ g_self).t()
            gbe += g_self.sum(0)
            for i in range(n - 1):
                g_i = g_total if mf_s is None else g_total * mf_s[:, :, :, i]
                g_i = relu_grad(g_i, h_oth[:, :, :, i], 0).view(-1, L)
                gWe += (x_oth[:, :, :, i].reshape(-1, F).t() @ g_i).t()
                gbe += g_i.sum(0)
        return None, None, None, None, gWe, gbe, gWg, gbg


def _slice(sl: slice, mf, count):
    """A chunk's rows of the masks of :meth:`_OneLayerFusion._masks`."""
    return (None, count) if mf is None else (mf[sl], count[sl])


def random_permutation(batch: int, num_agents: int, generator: torch.Generator | None = None,
                       device="cpu") -> torch.Tensor:
    """One uniformly random order of the agents per world: a long tensor (batch, num_agents)."""
    return torch.rand(batch, num_agents, generator=generator).argsort(dim=-1).to(device)


def group_division(perm: torch.Tensor, group_size: int = 3) -> torch.Tensor:
    """The paper's group division for every agent of every world.

    ``perm`` (B, N): a random order of the agents per world (see :func:`random_permutation`);
    or (B, N, N): one order per agent (row ``k`` for agent ``k``).
    Returns a long tensor (B, N, G, n) of agent indices with ``G = ceil((N - 1) / m)``
    groups of ``n = m + 1`` members, ``m = min(group_size - 1, N - 1)``; entry
    ``[b, k, g, 0]`` is ``k`` itself (k joins every group), the others of agent ``k`` are
    ``perm[b]`` without ``k``, cut in order. Example, 5 agents, identity order, N_g = 3::

        >>> group_division(torch.arange(5)[None], 3)[0, 0].tolist()
        [[0, 1, 2], [0, 3, 4]]
        >>> group_division(torch.arange(4)[None], 3)[0, 0].tolist()   # 3 others: agent 1 twice
        [[0, 1, 2], [0, 3, 1]]
    """
    if isinstance(group_size, bool) or not isinstance(group_size, int) or group_size < 2:
        raise ValueError(f"group_size: expected an int >= 2, got {group_size!r}")
    if perm.dim() not in (2, 3) or (perm.dim() == 3 and perm.shape[1] != perm.shape[2]):
        raise ValueError(f"perm: expected a (B, N) or (B, N, N) tensor, got shape {tuple(perm.shape)}")
    B, N = perm.shape[:2]
    ids = torch.arange(N, device=perm.device)
    if N == 1:
        return ids.view(1, 1, 1, 1).expand(B, 1, 1, 1).clone()
    m = min(group_size - 1, N - 1)
    full = perm.unsqueeze(1).expand(B, N, N) if perm.dim() == 2 else perm
    others = full[full != ids.view(1, N, 1)].view(B, N, N - 1)  # order kept, k removed
    G = math.ceil((N - 1) / m)
    pad = G * m - (N - 1)
    if pad:  # uneven: the first agents of the random order join a second group
        others = torch.cat([others, others[..., :pad]], dim=-1)
    groups = others.view(B, N, G, m)
    me = ids.view(1, N, 1, 1).expand(B, N, G, 1)
    return torch.cat([me, groups], dim=-1)


def gcn_layer(h: torch.Tensor, adj: torch.Tensor, linear: nn.Module, activation=torch.relu) -> torch.Tensor:
    """One graph-convolution layer ``act(D^-1/2 (A + I) D^-1/2 H W)`` on batched small graphs.

    ``h`` (..., n, F) node features, ``adj`` (..., n, n) edge weights without self loops
    (1 for an edge, 0 for none), ``linear`` the weight ``W`` (F -> F'). Self loops are
    added here, so an isolated node keeps ``act(h W)``.
    """
    n = adj.shape[-1]
    a = adj + torch.eye(n, dtype=adj.dtype, device=adj.device)
    d = a.sum(-1).rsqrt()
    a_hat = d.unsqueeze(-1) * a * d.unsqueeze(-2)
    return activation(a_hat @ linear(h))


class GroupInformationFusion(nn.Module):
    """Agent ``k``'s feature fused over all its groups (B, N, L).

    ``forward(pair_features, groups, alive)``:

    * ``pair_features`` (B, N, N, F): row ``[b, k, j]`` describes agent ``j`` as seen from
      agent ``k`` (relative position and velocity, see
      :func:`masp_lite.nets.masp.pair_features`); the node of ``k`` itself is ``[b, k, k]``;
    * ``groups`` (B, N, G, n) from :func:`group_division`;
    * ``alive`` (B, N) bool.

    Nodes are embedded (Linear + ReLU, F -> L), each subgraph runs ``layers`` GCN layers, and
    ``k``'s node (index 0 of each group) is averaged over the groups that have at least
    one alive other member (over all groups when none has).
    """

    def __init__(self, in_features: int, width: int = 32, layers: int = 1):
        super().__init__()
        self.embed = mlp([in_features, width], last_activation=True)
        self.gcn = nn.ModuleList(nn.Linear(width, width) for _ in range(layers))

    def forward(self, pair_features: torch.Tensor, groups: torch.Tensor, alive: torch.Tensor) -> torch.Tensor:
        B, N, G, n = groups.shape
        flat = groups.reshape(B, N, G * n)
        member = torch.gather(alive.unsqueeze(1).expand(B, N, N), 2, flat).view(B, N, G, n).clone()
        member[..., 0] = True                                           # k is always in its groups
        valid = member[..., 1:].any(-1) if n > 1 else member[..., 0]
        w = valid.to(pair_features.dtype)
        w = torch.where(w.sum(-1, keepdim=True) > 0, w, torch.ones_like(w))
        if len(self.gcn) == 1 and chunked() and not pair_features.requires_grad:
            # Only k's row of the one layer is needed; with unit edges it is the mean over the
            # group's members (see _OneLayerFusion).
            others = member[..., 1:]
            embed, gcn = self.embed[0], self.gcn[0]
            return _OneLayerFusion.apply(pair_features, groups, None if bool(others.all()) else others,
                                         w / w.sum(-1, keepdim=True), embed.weight, embed.bias, gcn.weight, gcn.bias)
        h = self.embed(pair_features)                               # (B, N, N, L)
        L = h.shape[-1]
        m = member.to(h.dtype)
        hg = torch.gather(h, 2, flat.unsqueeze(-1).expand(B, N, G * n, L)).view(B, N, G, n, L)
        adj = m.unsqueeze(-1) * m.unsqueeze(-2)
        adj = adj * (1 - torch.eye(n, dtype=h.dtype, device=h.device))  # edges 1 between members
        for layer in self.gcn:
            hg = gcn_layer(hg, adj, layer)
        mine = hg[..., 0, :]
        return (mine * w.unsqueeze(-1)).sum(2) / w.sum(-1, keepdim=True)
