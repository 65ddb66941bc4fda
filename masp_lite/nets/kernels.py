"""The chunked CPU kernels: parts of the networks computed a few worlds at a time, with hand-written backwards.

The paper's modules write the networks with plain torch ops, as the equations read. Three parts
of them see every (agent, goal) or (agent, other) pair, and at 50 agents a training minibatch
holds millions of such rows; autograd keeps every (rows, L) intermediate, and the update then
runs at memory speed. Each kernel here computes the same numbers a chunk of worlds at a time,
in the CPU cache, saves only its inputs and recomputes a chunk's forward before its gradient
(activation checkpointing):

* :class:`ScoreHead` — the Cross-Encoder's score MLP (eq. 4), :class:`masp_lite.nets.encoders.CrossEncoder`;
* :class:`OneLayerFusion` — the Group Information Fusion with one GCN layer (the paper's),
  :class:`masp_lite.nets.fusion.GroupInformationFusion`;
* :class:`PoolKernel` — the goal-free baselines' attention pooling and one-hop mean,
  :class:`masp_lite.nets.baselines.AttentionPool` and :class:`~masp_lite.nets.baselines.RadiusMean`.

Past the paper's scale one world alone is too big for the cache (1000 agents: about N^2 / 2 =
500,000 groups, 1.5 million pair rows), so the forwards of :class:`ScoreHead` and :class:`OneLayerFusion`
cut such a world into slices of agents (:func:`_chunks`). Every row is computed by the same operations
either way, so the numbers are the same, bit for bit (tested; the records at N <= 200 re-evaluate
unchanged). Measured in CPU time on one core of a loaded machine, one world of the shipped networks, the fusion
and the Goal Matcher's scores together, whole world -> slices: N = 200 30 -> 18 ms, N = 500 48 -> 33 ms,
N = 1000 357 -> 113 ms (research log, 2026-12-07).

A network part calls its kernel when its ``kernel`` flag is on (the default; a constructor argument) and
its inputs need no gradient (they are observations); :func:`use_kernels`
switches the kernels of a whole network off, the reference ``bench train`` measures them against. The kernels and
the plain ops agree to float rounding (tested, with ``gradcheck``). The paper's modules import
this one when they first call a kernel, so reading (or importing) MASP's path does not load it.

Why hand-written: torch has no fused op for these shapes. The gains (measured in each class's
docstring) come from never holding a whole minibatch's (rows, L) intermediates and from explicit
additions over a group's few members, which autograd (with or without ``torch.utils.checkpoint``)
does not do.
"""
from __future__ import annotations

import torch

__all__ = ["ScoreHead", "OneLayerFusion", "PoolKernel", "relu_grad", "use_kernels"]

SCORE_ROWS = 10_000
"""(agent, goal) pairs :class:`ScoreHead` processes at a time."""
FUSION_ROWS = 20_000
"""Pair rows (agents x group members) :class:`OneLayerFusion` processes at a time."""
POOL_ROWS = 20_000
"""(agent, other) rows :class:`PoolKernel` processes at a time."""


def use_kernels(module: torch.nn.Module, on: bool = True) -> torch.nn.Module:
    """Turn the kernels on or off in every part of ``module`` that has one (its ``kernel`` flag, which each
    part's constructor sets, on by default), as ``module.train(mode)`` sets ``training``; returns ``module``.
    Off, those parts use plain torch ops and autograd: the same numbers up to float rounding, the reference
    ``bench train`` measures the kernels against."""
    for part in module.modules():
        if hasattr(part, "kernel"):
            part.kernel = bool(on)
    return module


relu_grad = torch.ops.aten.threshold_backward
"""``relu_grad(grad, relu_output, 0)``: ``grad`` where the ReLU's output is > 0 — every kernel's ReLU backward,
faster than multiplying by a mask."""


class ScoreHead(torch.autograd.Function):
    """``relu(hq_k + hk_j + D_kj w_D) . w2 + b2`` for every (agent, goal) pair, chunked.

    ``apply(hq (B, N, L), hk (B, M, L), dist (B, N, M, C), wd (L, C), w2 (1, L), b2 (1,))
    -> (B, N, M)``; ``dist`` needs no gradient (an observation). The (B, N, M, L) hidden
    layer of eq. 4's MLP is never stored: it is computed a few worlds at a time, in cache,
    and recomputed in the backward. Measured on one core, 50 agents and 50 goals, a
    240-row minibatch: the Cross-Encoder's forward and backward 0.43 s -> 0.11 s (whole
    training: ``bench train``); the numbers agree with autograd to float rounding (tested).
    """

    @staticmethod
    def _hidden(hq, hk, dist, wd):
        h = hq.unsqueeze(2) + hk.unsqueeze(1)
        h.view(-1, h.shape[-1]).addmm_(dist.reshape(-1, dist.shape[-1]), wd.t())
        return h.relu_()

    @staticmethod
    def forward(ctx, hq, hk, dist, wd, w2, b2):
        B, N, M = dist.shape[:3]
        step = max(1, SCORE_ROWS // max(N * M, 1))
        out = []
        for s, a in _chunks(B, N, step, M, SCORE_ROWS):
            worlds = slice(s, s + step)
            out.append((ScoreHead._hidden(hq[worlds, a], hk[worlds], dist[worlds, a], wd) @ w2[0]) + b2)
        ctx.save_for_backward(hq, hk, dist, wd, w2)
        ctx.step = step
        return _join(out, B, step)

    @staticmethod
    def backward(ctx, grad):
        hq, hk, dist, wd, w2 = ctx.saved_tensors
        L, C = wd.shape
        ghq, ghk = torch.empty_like(hq), torch.empty_like(hk)
        gwd, gw2 = torch.zeros_like(wd), torch.zeros_like(w2)
        for s in range(0, hq.shape[0], ctx.step):
            sl = slice(s, s + ctx.step)
            h = ScoreHead._hidden(hq[sl], hk[sl], dist[sl], wd)
            g = grad[sl]
            gw2 += (h.reshape(-1, L).t() @ g.reshape(-1)).unsqueeze(0)
            gh = relu_grad(g.unsqueeze(-1) * w2[0], h, 0)
            ghq[sl], ghk[sl] = gh.sum(2), gh.sum(1)
            gwd += (dist[sl].reshape(-1, C).t() @ gh.reshape(-1, L)).t()
        return ghq, ghk, None, gwd, gw2, grad.sum().reshape(1)


def _linear_relu(x: torch.Tensor, weight_t: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """``relu(x @ weight_t + bias)`` for (..., F) rows: one ``addmm``, then ReLU in place."""
    return torch.addmm(bias, x.reshape(-1, x.shape[-1]), weight_t).relu_().view(*x.shape[:-1], weight_t.shape[1])


class OneLayerFusion(torch.autograd.Function):
    """The one-layer fusion, a few worlds at a time, with a hand-written backward.

    ``apply(pair, groups, others_alive, weight, We, be, Wg, bg) -> (B, N, L)``, for pair
    features that need no gradient (they are observations): ``others_alive`` (B, N, G, n-1)
    marks the alive other members (``None``: all alive), ``weight`` (B, N, G) the groups'
    weights in the mean (rows sum to 1). Per group, ``k``'s row of one GCN layer with unit
    edges is ``relu(Wg mean(h_members) + bg)`` with ``h = relu(We x + be)``.

    Why: at 50 agents a minibatch holds millions of pair rows, and autograd keeps every
    (rows, L) intermediate: the update then runs at memory speed. Here each chunk of
    ``FUSION_ROWS`` pair rows stays in the CPU cache, nothing but the inputs (with the row
    numbers and masks that are made from them once per call) is saved, and the backward
    recomputes a chunk's forward before its gradient (activation checkpointing); sums over
    the few members of a group are explicit additions (much faster than ``sum`` over a
    short axis), and a chunk reads its nodes with one ``index_select`` of row numbers.
    Measured on one core, 50 agents, a 720-row minibatch (best of 4): forward and backward
    2.0 s with autograd -> 0.37 s; the numbers agree with the general path
    (:func:`masp_lite.nets.fusion.gcn_layer`) to float rounding (tested, with ``gradcheck``).
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
        step = max(1, FUSION_ROWS // (N * G * n))
        We_t, Wg_t = We.t().contiguous(), Wg.t().contiguous()
        pair_rows = pair.reshape(-1, pair.shape[-1])
        self_rows, other_rows = OneLayerFusion._rows(groups)
        mf, count = OneLayerFusion._masks(others_alive, groups, pair.dtype)
        out = []
        for s, a in _chunks(B, N, step, G * n, FUSION_ROWS):
            sl = (slice(s, s + step), a)
            z = OneLayerFusion._chunk(pair_rows, self_rows[sl], other_rows[sl], *_slice(sl, mf, count),
                                       We_t, be, Wg_t, bg)[-1]
            out.append((z * weight[sl].unsqueeze(-1)).sum(2))
        ctx.save_for_backward(pair_rows, self_rows, other_rows, mf, weight, We, be, Wg, bg)
        ctx.step, ctx.count = step, count
        return _join(out, B, step)

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
            x_self, x_oth, h_self, h_oth, a, z = OneLayerFusion._chunk(pair_rows, self_rows[sl], other_rows[sl],
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


def _slice(sl, mf, count):
    """A chunk's rows of the masks of :meth:`OneLayerFusion._masks`."""
    return (None, count) if mf is None else (mf[sl], count[sl])


def _chunks(B: int, N: int, step: int, per_agent: int, rows: int):
    """The forward's chunks ``(first world, agents)``: ``step`` whole worlds at a time while a world's
    ``N * per_agent`` rows fit in ``rows`` (the backward's chunks too), else one world in slices of
    ``rows // per_agent`` agents, so that a world of hundreds of agents (tens of MB of pair rows) is
    still computed in the CPU cache: every row's numbers are the same either way, only fewer at once."""
    agents = N if N * per_agent <= rows else max(1, rows // per_agent)
    return [(s, slice(a, a + agents)) for s in range(0, B, step) for a in range(0, N, agents)]


def _join(out: list, B: int, step: int) -> torch.Tensor:
    """The (B, N, ...) result of the chunks of :func:`_chunks`, in their order."""
    per_world = len(out) // len(range(0, B, step))
    return torch.cat(out if per_world == 1 else [torch.cat(out[i:i + per_world], 1)
                                                 for i in range(0, len(out), per_world)])


class PoolKernel(torch.autograd.Function):
    """``sum_s alpha_s relu(We x_s + be)`` over each agent's rows, a few worlds at a time.

    ``apply(rows (B, N, S, F), select, W, b, w2, b2) -> (B, N, L)`` for rows that need no
    gradient (observations). Two modes:

    * attention (:class:`~masp_lite.nets.baselines.AttentionPool`): ``W`` (2L, F) and ``b`` (2L,) stack the score
      MLP's first layer over the embedding; ``alpha`` is the softmax over the rows ``select``
      (B, N, S) bool marks (``None``: all) of ``relu(W1 x + b1) . w2 + b2`` (zeros when none is marked);
    * fixed weights (:class:`~masp_lite.nets.baselines.RadiusMean`): ``w2`` and ``b2`` are ``None``, ``W`` (L, F) is
      the embedding and ``select`` (B, N, S) holds ``alpha`` itself.

    Only the inputs are saved; the backward recomputes each chunk's forward before its
    gradient, so every (rows, L) intermediate stays in the CPU cache.
    """

    @staticmethod
    def _chunk(x, select, W_t, b, w2, b2):
        bs, N, S, F = x.shape
        h = torch.addmm(b, x.reshape(-1, F), W_t).relu_()                     # (r, 2L) or (r, L)
        L = w2.shape[1] if w2 is not None else h.shape[1]
        e = h[:, -L:].reshape(bs * N, S, L) if w2 is not None else h.view(bs * N, S, L)
        if w2 is None:
            return h, e, select.reshape(bs * N, S)
        s = (h[:, :L] @ w2[0]).add_(b2).view(bs * N, S)
        if select is not None:
            s = s.masked_fill_(~select.reshape(bs * N, S), float("-inf"))
        return h, e, torch.softmax(s, -1).nan_to_num_(nan=0.0)

    @staticmethod
    def forward(ctx, rows, select, W, b, w2, b2):
        B, N, S, _ = rows.shape
        step = max(1, POOL_ROWS // max(N * S, 1))
        W_t = W.t().contiguous()
        out = []
        for s in range(0, B, step):
            sl = slice(s, s + step)
            _, e, alpha = PoolKernel._chunk(rows[sl], None if select is None else select[sl], W_t, b, w2, b2)
            out.append(torch.bmm(alpha.unsqueeze(1), e).view(-1, N, e.shape[-1]))
        ctx.save_for_backward(rows, select, W, b, w2, b2)
        ctx.step = step
        return torch.cat(out)

    @staticmethod
    def backward(ctx, grad):
        rows, select, W, b, w2, b2 = ctx.saved_tensors
        B, N, S, F = rows.shape
        W_t = W.t().contiguous()
        gW, gb = torch.zeros_like(W), torch.zeros_like(b)
        gw2 = None if w2 is None else torch.zeros_like(w2)
        gb2 = None if b2 is None else torch.zeros_like(b2)
        for s in range(0, B, ctx.step):
            sl = slice(s, s + ctx.step)
            x = rows[sl].reshape(-1, F)
            h, e, alpha = PoolKernel._chunk(rows[sl], None if select is None else select[sl], W_t, b, w2, b2)
            L = e.shape[-1]
            g = grad[sl].reshape(-1, 1, L)                                    # (bN, 1, L)
            gh = torch.empty_like(h)
            gh[:, -L:] = relu_grad(alpha.unsqueeze(-1) * g, e, 0).reshape(-1, L)
            if w2 is not None:
                g_alpha = torch.bmm(e, g.transpose(1, 2)).squeeze(-1)          # (bN, S)
                g_s = alpha * (g_alpha - (alpha * g_alpha).sum(-1, keepdim=True))
                hs = h[:, :L]
                g_s = g_s.reshape(-1)
                gw2 += (hs.t() @ g_s).unsqueeze(0)
                gb2 += g_s.sum()
                gh[:, :L] = relu_grad(g_s.unsqueeze(-1) * w2[0], hs, 0)
            gW += gh.t() @ x
            gb += gh.sum(0)
        return None, None, gW, gb, gw2, gb2
