"""MASP's rewards: ``R_GM`` (paper eq. 1) for the Goal Matcher, ``R_CAE`` (eq. 5) for the executor
(the goal-free baselines' reward is :func:`masp_lite.algos.goal_sources.coverage_reward`).

**R_GM** (:func:`goal_matcher_reward`), per agent ``k`` each global step, with ``g_m^k``
the goal the Goal Matcher picked and ``g_h^k`` the Hungarian goal (scipy's
``linear_sum_assignment`` via :func:`masp_lite.algos.assignment.hungarian`, one call per
world)::

    R_GM^k = 0                        if g_m^k == g_h^k
           = -(1 + N_repeat / N)      if g_m^k != g_h^k and N_repeat > 0
           = -(1 - D_h / D_m)         if g_m^k != g_h^k and N_repeat == 0

``N_repeat``: other alive agents that picked the same goal as ``k``; ``N``: alive agents;
``D_m`` and ``D_h``: the team's total agent-to-goal distance under the picked and the
Hungarian goals (:func:`masp_lite.algos.assignment.assignment_cost`). Dropped agents get 0.
The paper does not give the reference's costs: ``RewardConfig.gm_reference`` chooses
distances (default) or squared distances.
With varying teams the Hungarian reference uses the landmarks not yet reached (as
``h-greedy`` does).

**R_CAE** (:func:`executor_reward`), per agent every step, after the step::

    R_CAE^k = alpha * R_b^k + beta * R_d^k + gamma * R_c^k

The paper names the terms but not their forms or coefficients; chosen here (after
MAGE-X's executor reward, the code MASP descends from):

* ``R_b`` (complete bonus) = 1 when agent ``k`` is within ``r_agent + r_landmark`` of
  its assigned goal, else 0;
* ``R_d`` (distance penalty) = ``-dist(agent, assigned goal) / (world_size / 2)`` — map
  normalised so the term has the same size on every map;
* ``R_c`` (collision penalty) = ``-(agent k's contacts)`` with agents and obstacles;
* ``alpha = 1``, ``beta = 1``, ``gamma = 1`` by default (``RewardConfig.bonus_coef``,
  ``distance_coef``, ``collision_coef``): one collision costs as much as one step on the
  goal earns.
"""
from __future__ import annotations

import torch

from .assignment import assignment_cost, hungarian

__all__ = ["goal_matcher_reward", "executor_reward", "complete_bonus", "repeat_counts"]


def repeat_counts(goals: torch.Tensor, alive: torch.Tensor, num_goals: int) -> torch.Tensor:
    """``N_repeat`` (B, N): how many *other* alive agents picked the same goal as each agent."""
    onehot = torch.nn.functional.one_hot(goals.clamp(min=0), num_goals) * alive.unsqueeze(-1)
    per_goal = onehot.sum(1)                                              # (B, M)
    return torch.gather(per_goal, 1, goals.clamp(min=0)) - alive.long()


def goal_matcher_reward(agent_pos, goal_pos, goals, alive, goal_mask=None, reference=None,
                        power: float = 1.0) -> torch.Tensor:
    """Equation 1 for every agent of every world: a float tensor (B, N).

    ``goals`` (B, N) long: the Goal Matcher's picks; ``alive`` (B, N) bool; ``goal_mask``
    (B, M) bool: goals the reference may use (``None``: all); ``reference``: a precomputed
    reference assignment (B, N) (computed here when ``None``): the Hungarian assignment
    minimising the total of ``distance ** power``; ``D_m``, ``D_h`` are totals of that cost
    (power 1: total distance, the paper's reading; 2: ``RewardConfig.gm_reference="squared"``).
    """
    if goals.shape != alive.shape or goals.dtype != torch.long:
        raise ValueError(f"goals: expected a long tensor of shape {tuple(alive.shape)}, got "
                         f"{tuple(goals.shape)} {goals.dtype}")
    h = reference if reference is not None else hungarian(agent_pos, goal_pos, alive, goal_mask, power)
    picked = torch.where(alive, goals, torch.full_like(goals, -1))
    d_m = assignment_cost(agent_pos, goal_pos, picked, power)                # (B,)
    d_h = assignment_cost(agent_pos, goal_pos, h, power)
    n_alive = alive.sum(1, keepdim=True).clamp(min=1).to(agent_pos.dtype)
    n_rep = repeat_counts(goals, alive, goal_pos.shape[1]).to(agent_pos.dtype)
    ratio = (d_h / d_m.clamp(min=1e-9)).unsqueeze(1).expand_as(n_rep)
    r = torch.where(n_rep > 0, -(1 + n_rep / n_alive), -(1 - ratio))
    r = torch.where(goals == h, torch.zeros_like(r), r)
    return torch.where(alive, r, torch.zeros_like(r))


def executor_reward(agent_pos, goal_pos, agent_collisions, alive, reach: float, world_size: float,
                    alpha: float = 1.0, beta: float = 1.0, gamma: float = 1.0) -> torch.Tensor:
    """Equation 5 for every agent: ``alpha R_b + beta R_d + gamma R_c``, a float tensor (B, N).

    ``agent_pos`` and ``goal_pos`` (the assigned goal of each agent) are (B, N, 2) after
    the step; ``agent_collisions`` (B, N) the contacts of each agent after the step.
    """
    dist = (goal_pos - agent_pos).norm(dim=-1)
    r_b = complete_bonus(dist, reach)
    r_d = -dist / (world_size / 2)
    r_c = -agent_collisions.to(agent_pos.dtype)
    r = alpha * r_b + beta * r_d + gamma * r_c
    return torch.where(alive, r, torch.zeros_like(r))


def complete_bonus(dist: torch.Tensor, reach: float, alive: torch.Tensor | None = None) -> torch.Tensor:
    """``R_b`` (B, N) from each agent's distance ``dist`` (B, N) to its assigned goal: 1
    within ``reach``, else 0 (0 for dropped agents when ``alive`` is given)."""
    r_b = (dist < reach).to(dist.dtype)
    return r_b if alive is None else torch.where(alive, r_b, torch.zeros_like(r_b))
