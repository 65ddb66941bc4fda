"""The Goal Matcher's goals in training: distinct goals drawn agent by agent, and their log-probabilities.

The Goal Matcher gives every agent ``k`` a categorical ``S_intra^k`` over the goals (eq. 4);
``R_GM`` (eq. 1) punishes two agents choosing one goal. In training the agents draw in a
random order, each from its own categorical restricted to the goals not yet taken by agents
earlier in the order (:func:`sequential_sample`): an autoregressive factorisation of a joint
policy over distinct goals. Agent ``k``'s log-probability for PPO is that of its restricted
categorical (:func:`conditional_logits` rebuilds the restriction from the stored order and
picks), so each agent's PPO ratio is its conditional one. How the same scores become goals
when the policy acts greedily is :mod:`masp_lite.nets.decoding`'s.

Masks: dropped agents (``alive`` False) take no goal and block none. ``goal_mask``
(B, M) marks the goals that may be chosen (varying teams: those not reached yet). When
the allowed goals run out (more alive agents than allowed goals) the remaining agents may
share allowed goals; with no allowed goal at all, every goal is allowed
(:func:`allowed_goals`).
"""
from __future__ import annotations

import torch

__all__ = ["sequential_sample", "conditional_logits", "taken_before", "allowed_goals", "MASKED"]

MASKED = -1e9
"""Logit given to a goal an agent may not choose (finite, so entropies stay finite)."""


def allowed_goals(goal_mask: torch.Tensor | None, like: torch.Tensor) -> torch.Tensor:
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
    allowed = allowed_goals(goal_mask, logits).unsqueeze(1)                      # (B, 1, M)
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
    allowed = allowed_goals(goal_mask, logits)
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
