"""The Goal Matcher's graph encoders: ``SelfEncoder`` (eqs. 2-3) and ``CrossEncoder`` (eq. 4).

Paper, section "Goal Matcher": agents and goals each form a fully connected graph whose
edges start at 1. The **Self-Encoder** replaces those edges by an attention matrix and
updates every node from its neighbours; the **Cross-Encoder** scores agent ``k`` against
every goal. Shapes are batch-first: ``X`` is (B, N, L), with ``L`` = 32 in the paper.

Equation 2 (:func:`s_inter`)::

    S_inter = Softmax((W_query X^T)^T (W_key X^T))        # (N, N), row i sums to 1

Equation 3 (:func:`node_update`)::

    Y = X + MLP(Concat(X, (W_value X^T) S_inter^T))       # the i-th new row mixes S_inter[i, j] v_j

Equation 4 (:class:`CrossEncoder`)::

    S_intra^k = Softmax_j(MLP(Concat(W_query Y_A^k, W_key Y_T^j, D_kj)))

Choices where the paper is silent, each documented where it is made: the attention
logits are divided by ``sqrt(L)`` (a constant the projections could absorb; it keeps the
softmax soft at initialisation), masked nodes (dropped agents) are left out of every
softmax, and the MLPs have one hidden layer of width ``L`` with ReLU.

Why hand-written: both are a few lines of batched tensor algebra; ``torch.nn.MultiheadAttention``
has no residual MLP node update nor the distance input of eq. 4, so wrapping it would hide
the equations this module exists to show.
"""
from __future__ import annotations

import math

import torch
from torch import nn

__all__ = ["mlp", "s_inter", "node_update", "SelfEncoder", "CrossEncoder", "masked_softmax"]


def mlp(sizes: list[int], last_activation: bool = False) -> nn.Sequential:
    """Linear layers of the given widths with ReLU between them.

    >>> mlp([4, 32, 1])
    Sequential(
      (0): Linear(in_features=4, out_features=32, bias=True)
      (1): ReLU()
      (2): Linear(in_features=32, out_features=1, bias=True)
    )
    """
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2 or last_activation:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


def masked_softmax(logits: torch.Tensor, mask: torch.Tensor | None, dim: int = -1) -> torch.Tensor:
    """Softmax over ``dim`` where ``mask`` is False contributes nothing.

    A row whose entries are all masked returns zeros instead of NaN.
    """
    if mask is None:
        return torch.softmax(logits, dim=dim)
    logits = logits.masked_fill(~mask, float("-inf"))
    out = torch.softmax(logits, dim=dim)
    return torch.nan_to_num(out, nan=0.0)


def s_inter(query: torch.Tensor, key: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Equation 2: the attention edge matrix ``S_inter`` (B, N, N) from projected nodes.

    ``query`` and ``key`` are ``W_query X`` and ``W_key X`` as rows (B, N, L);
    ``mask`` (B, N) bool marks the nodes that exist (``None``: all). Entry ``[b, i, j]`` is
    how much node ``i`` attends to node ``j``; every row of existing nodes sums to 1 over
    existing ``j``. Logits are scaled by ``1 / sqrt(L)``.
    """
    logits = query @ key.transpose(-1, -2) / math.sqrt(query.shape[-1])
    col_mask = None if mask is None else mask.unsqueeze(-2).expand_as(logits)
    return masked_softmax(logits, col_mask, dim=-1)


def node_update(x: torch.Tensor, value: torch.Tensor, s: torch.Tensor, update_mlp: nn.Module) -> torch.Tensor:
    """Equation 3: ``Y = X + MLP([X, S_inter V])`` for node rows ``x`` (B, N, L).

    ``value`` is ``W_value X`` as rows (B, N, L) and ``s`` the edge matrix (B, N, N), so
    ``s @ value`` is the paper's ``(W_value X^T) S_inter^T`` written row-wise: node ``i``
    receives ``sum_j S_inter[i, j] v_j``. ``update_mlp`` maps 2L -> L.
    """
    return x + update_mlp(torch.cat([x, s @ value], dim=-1))


class SelfEncoder(nn.Module):
    """Self-Encoder (eqs. 2-3): one attention edge update and one residual node update.

    ``forward(x, mask=None) -> (y, s_inter)`` with ``x`` (B, N, L), ``mask`` (B, N) bool.
    Works for any ``N``: every weight acts per node or per pair. Masked nodes keep their
    input row (they are ignored by the others and by later pooling).
    """

    def __init__(self, width: int = 32):
        super().__init__()
        self.width = width
        self.query = nn.Linear(width, width, bias=False)
        self.key = nn.Linear(width, width, bias=False)
        self.value = nn.Linear(width, width, bias=False)
        self.update = mlp([2 * width, width, width])

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None = None):
        s = s_inter(self.query(x), self.key(x), mask)
        y = node_update(x, self.value(x), s, self.update)
        if mask is not None:
            y = torch.where(mask.unsqueeze(-1), y, x)
        return y, s


class CrossEncoder(nn.Module):
    """Cross-Encoder (eq. 4): matching-score logits of every agent against every goal.

    ``forward(y_a, y_t, dist, goal_mask=None) -> logits`` with agent nodes ``y_a``
    (B, N, L), goal nodes ``y_t`` (B, M, L) and L2 distances ``dist`` (B, N, M) (in
    map-normalised units), or (B, N, M, C) with ``C = distance_channels`` distance-derived
    inputs per pair. The score of (k, j) is ``MLP([W_q y_a^k, W_k y_t^j, D_kj])``;
    :meth:`scores` applies the softmax over goals (``S_intra^k``). The logits are what the
    Goal Matcher's categorical distribution uses. Masked goals get ``-inf``. ``kernel``: distances that need
    no gradient are scored by :class:`~masp_lite.nets.kernels.ScoreHead` (see ``kernels.use_kernels``).
    """

    def __init__(self, width: int = 32, distance_channels: int = 1, kernel: bool = True):
        super().__init__()
        self.width, self.distance_channels, self.kernel = width, distance_channels, kernel
        self.query = nn.Linear(width, width, bias=False)
        self.key = nn.Linear(width, width, bias=False)
        self.score = mlp([2 * width + distance_channels, width, 1])

    def forward(self, y_a, y_t, dist, goal_mask=None) -> torch.Tensor:
        L = y_a.shape[-1]
        first, rest = self.score[0], self.score[1:]
        # The first layer of MLP([q, k, D]) is W_q' q + W_k' k + w_D D + b: apply it to the N
        # agents and M goals separately and broadcast, instead of to all N x M concatenations.
        w = first.weight
        hq = self.query(y_a) @ w[:, :L].T                                   # (B, N, L)
        hk = self.key(y_t) @ w[:, L:2 * L].T                                # (B, M, L)
        if dist.dim() == 3:
            dist = dist.unsqueeze(-1)
        if dist.requires_grad or not self.kernel:  # the plain formula
            logits = rest(hq.unsqueeze(2) + hk.unsqueeze(1) + dist @ w[:, 2 * L:].T + first.bias).squeeze(-1)
        else:  # the same numbers, chunked (eq. 4's hidden layer is never stored whole)
            from .kernels import ScoreHead
            out = rest[1]
            logits = ScoreHead.apply(hq + first.bias, hk, dist, w[:, 2 * L:], out.weight, out.bias)
        if goal_mask is not None:
            logits = logits.masked_fill(~goal_mask.unsqueeze(1), float("-inf"))
        return logits

    def scores(self, y_a, y_t, dist, goal_mask=None) -> torch.Tensor:
        """``S_intra`` (B, N, M): each agent's softmax matching scores over the goals."""
        return torch.softmax(self.forward(y_a, y_t, dist, goal_mask), dim=-1)
