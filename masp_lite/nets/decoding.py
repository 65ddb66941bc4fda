"""Turning the Goal Matcher's per-agent scores into goals: independent or conflict-free.

The paper's Goal Matcher gives every agent ``k`` a categorical ``S_intra^k`` over the goals
(eq. 4) and says agent ``k`` "selects the goal with the highest matching score"; ``R_GM``
(eq. 1) punishes two agents choosing one goal. Read literally, each agent decides alone
(:func:`independent_goals`). Measured on ``mpe-20`` (evaluation seed 0, 100 episodes):
a Goal Matcher trained with independent sampling left several agents on one landmark,
SR 0.59, against 0.98 for the same networks decoded without conflicts; the shipped
weights (trained with the sequential draw below) score SR 0.68 decoded independently and
1.00 conflict-free. We therefore decode **conflict-free** by
default, a choice the paper leaves open (it never states how ties between agents are
broken), and keep the literal rule as ``decode="independent"`` for comparison:

* **acting greedily** (evaluation, :func:`joint_argmax`): the assignment of distinct goals
  to the alive agents that minimises ``sum_k (-log S_intra^k(g_k))^2``. This is scipy's
  ``linear_sum_assignment`` on the squared ``-log S_intra``, one call per world (the solver
  the Hungarian reference uses, here on learned scores instead of distances). Squaring
  keeps any agent from being left with a goal it scores poorly: Steps waits for the last
  landmark, so one agent sent to a goal it barely chose costs more than several small
  compromises. The unsquared sum (``power=1``, the most likely distinct assignment) needs
  more Steps on validation layouts (evaluation seeds 100-102 x 100, same weights): mpe-50
  50.13 against 46.89 squared (training seed 0), mpe-20 24.93 / 27.85 / 24.74 against
  24.10 / 25.94 / 23.82 (seeds 0-2), drone-20 343 against 325; mpe-5, mpe-20to10 and
  mpe-50to20 within 1 % (research log, "the Goal Matcher's decoding");
* **sampling** (training, :func:`sequential_sample`): agents draw in a random order, each
  from its own categorical restricted to the goals not yet taken by agents earlier in
  the order (an autoregressive factorisation of a joint policy over distinct goals).
  Agent ``k``'s log-probability for PPO is that of its restricted categorical
  (:func:`conditional_logits` rebuilds the restriction from the stored order and picks),
  so each agent's PPO ratio is its conditional one.

Masks: dropped agents (``alive`` False) take no goal and block none. ``goal_mask``
(B, M) marks the goals that may be chosen (varying teams: those not reached yet). When
the allowed goals run out (more alive agents than allowed goals) the remaining agents may
share allowed goals; with no allowed goal at all, every goal is allowed.
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

__all__ = ["DECODERS", "independent_goals", "random_goals", "joint_argmax", "sequential_sample", "conditional_logits",
           "taken_before", "MASKED"]

DECODERS = ("joint", "independent")
"""``joint``: conflict-free, squared costs (default); ``independent``: every agent alone, duplicates allowed."""

MASKED = -1e9
"""Logit given to a goal an agent may not choose (finite, so entropies stay finite)."""


def _allowed(goal_mask: torch.Tensor | None, like: torch.Tensor) -> torch.Tensor:
    """(B, M) bool: ``goal_mask``, or every goal where it allows none (or is ``None``)."""
    B, M = like.shape[0], like.shape[-1]
    if goal_mask is None:
        return torch.ones(B, M, dtype=torch.bool, device=like.device)
    return goal_mask | ~goal_mask.any(-1, keepdim=True)


def taken_before(goals: torch.Tensor, rank: torch.Tensor, alive: torch.Tensor, num_goals: int) -> torch.Tensor:
    """(B, N, M) bool: goal ``j`` was picked by an alive agent that comes before ``k`` in the order.

    ``rank`` (B, N): each agent's position in the drawing order (0 draws first).
    """
    onehot = torch.nn.functional.one_hot(goals.clamp(min=0), num_goals).to(torch.float32)
    earlier = (rank.unsqueeze(1) < rank.unsqueeze(2)) & alive.unsqueeze(1)      # [b, k, i]: i before k
    return (earlier.to(torch.float32) @ onehot) > 0


def conditional_logits(logits: torch.Tensor, goals: torch.Tensor, rank: torch.Tensor, alive: torch.Tensor,
                       goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """Logits (B, N, M) of each agent's restricted categorical in :func:`sequential_sample`.

    Goals taken earlier in the order, and goals outside ``goal_mask``, get :data:`MASKED`;
    an agent left with nothing (more agents than allowed goals) keeps the allowed goals.
    """
    allowed = _allowed(goal_mask, logits).unsqueeze(1)                           # (B, 1, M)
    free = allowed & ~taken_before(goals, rank, alive, logits.shape[-1])
    free = torch.where(free.any(-1, keepdim=True), free, allowed)
    return logits.masked_fill(~free, MASKED)


def sequential_sample(logits: torch.Tensor, alive: torch.Tensor, generator: torch.Generator,
                      goal_mask: torch.Tensor | None = None):
    """Distinct goals drawn agent by agent in a random order: ``(goals, logp, rank)``.

    ``logits`` (B, N, M) are the Goal Matcher's; ``goals`` (B, N) long, ``logp`` (B, N) each
    agent's log-probability under its restricted categorical, ``rank`` (B, N) the order
    (store it: the update needs it to rebuild the restrictions). The loop runs over order
    positions (``N`` iterations), each vectorised over the worlds.
    """
    B, N, M = logits.shape
    rank = torch.rand(B, N, generator=generator).argsort(-1).argsort(-1)
    order = rank.argsort(-1)                                                     # order[:, r] = agent drawing r-th
    allowed = _allowed(goal_mask, logits)
    taken = torch.zeros(B, M, dtype=torch.bool)
    goals = torch.zeros(B, N, dtype=torch.long)
    gumbel = -torch.log(-torch.log(torch.rand(B, N, M, generator=generator).clamp(1e-10, 1.0)))
    rows = torch.arange(B)
    for r in range(N):
        k = order[:, r]
        free = allowed & ~taken
        free = torch.where(free.any(-1, keepdim=True), free, allowed)
        pick = (logits[rows, k].masked_fill(~free, MASKED) + gumbel[rows, k]).argmax(-1)
        goals[rows, k] = pick
        taken[rows, pick] |= alive[rows, k]
    logp = torch.log_softmax(conditional_logits(logits, goals, rank, alive, goal_mask), -1)
    logp = torch.gather(logp, -1, goals.unsqueeze(-1)).squeeze(-1)
    return goals, logp, rank


def random_goals(alive: torch.Tensor, num_goals: int, generator: torch.Generator,
                 goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """Distinct goals drawn uniformly at random without replacement (B, N): "MASP w. RG".

    :func:`sequential_sample` with equal logits, so an agent left with nothing (more alive
    agents than allowed goals) and dropped agents are treated alike."""
    B, N = alive.shape
    logits = torch.zeros(B, N, num_goals, device=alive.device)
    return sequential_sample(logits.cpu(), alive.cpu(), generator,
                             None if goal_mask is None else goal_mask.cpu())[0].to(alive.device)


def independent_goals(logits: torch.Tensor, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """The paper's literal rule: every agent takes its own highest-scoring allowed goal."""
    return logits.masked_fill(~_allowed(goal_mask, logits).unsqueeze(1), MASKED).argmax(-1)


def joint_argmax(logits: torch.Tensor, alive: torch.Tensor, goal_mask: torch.Tensor | None = None,
                 power: float = 2.0) -> torch.Tensor:
    """Distinct goals minimising the summed ``(-log S) ** power`` of the alive agents, per world (B, N).

    Solved by ``linear_sum_assignment`` on ``(-log_softmax(logits)) ** power`` over the alive
    agents and allowed goals (``power=2``: the policies' decoding; ``power=1``: the most likely
    distinct assignment, kept for comparison). Alive agents
    left without a goal (more of them than allowed goals) and dropped agents take their own
    best allowed goal.
    """
    allowed = _allowed(goal_mask, logits)
    fallback = independent_goals(logits, allowed)
    cost = (-torch.log_softmax(logits.masked_fill(~allowed.unsqueeze(1), MASKED), -1)).detach().cpu().numpy()
    if power != 1.0:
        cost = cost.astype(np.float64) ** power
    am, gm = alive.cpu().numpy(), allowed.cpu().numpy()
    out = fallback.cpu().numpy().copy()
    for b in range(cost.shape[0]):  # scipy solves one matrix at a time
        rows, cols = np.flatnonzero(am[b]), np.flatnonzero(gm[b])
        if len(rows) == 0:
            continue
        r, c = linear_sum_assignment(cost[b][np.ix_(rows, cols)])
        out[b, rows[r]] = cols[c]
    return torch.from_numpy(out).to(logits.device)
