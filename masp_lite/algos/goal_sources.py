"""The goal sources of the ablations and baselines that train no Goal Matcher (``NetConfig.goal_matcher``).

MASP's trainer (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) samples goals from its Goal
Matcher; these sources stand in for it, beside the paper's path:

* ``random`` ("MASP w. RG"): distinct random goals when the episode starts, redrawn only when
  the team changes;
* ``hungarian`` (``h-mappo``, or a drone curriculum stage): the Hungarian assignment every
  global step;
* ``none`` (``mappo``, ``darl1n``): no goals; the executor sees every landmark and the team
  shares a coverage reward (:func:`coverage_reward`) in place of R_CAE.

With a varying team, landmarks already reached count for SR, so goals are drawn among the rest.
"""
from __future__ import annotations

import torch

from ..nets.decoding import random_goals
from .team import hungarian_goals

__all__ = ["scripted_goals", "coverage_reward"]


def scripted_goals(source: str, t: int, obs: dict, goals, drawn_for, global_step: int, generator: torch.Generator,
                   varying: bool):
    """``(goals (B, N) or None, the alive mask they were drawn for)`` of step ``t`` from ``source``."""
    goal_mask = ~obs["reached"] if varying else None  # landmarks reached count for SR: pick among the rest
    if source == "none":
        return None, drawn_for
    if source == "random":  # redrawn only when the team changes
        if goals is None or not torch.equal(obs["alive"], drawn_for):
            return random_goals(obs["alive"], obs["landmark_pos"].shape[1], generator, goal_mask), \
                obs["alive"].clone()
        return goals, drawn_for
    if t % global_step:
        return goals, drawn_for
    if varying:  # every landmark reached: any of them
        goal_mask = goal_mask | obs["reached"].all(-1, keepdim=True)
    return hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"], goal_mask), drawn_for


def coverage_reward(agent_pos, landmark_pos, agent_collisions, alive, reach: float, world_size: float,
                    alpha: float = 1.0, beta: float = 1.0, gamma: float = 1.0) -> torch.Tensor:
    """The goal-free baselines' reward (``mappo``, ``darl1n``), (B, N), in MPE simple_spread's style.

    With no goals there is no per-agent target: the team shares simple_spread's coverage
    terms, and each agent pays for its own contacts. Scaled like R_CAE so that the same
    coefficients (``RewardConfig``) mean the same::

        R^k = alpha * (fraction of landmarks covered)
              - beta * mean_l min_a dist(l, a) / (world_size / 2)      (alive agents a)
              - gamma * (agent k's contacts)

    A landmark is covered when an alive agent is within ``reach`` of it. Dropped agents get 0.
    """
    d = torch.cdist(landmark_pos, agent_pos).masked_fill(~alive.unsqueeze(1), float("inf"))   # (B, M, N)
    nearest = d.min(-1).values.clamp(max=2 * world_size)                                      # no agent: far
    team = alpha * (nearest < reach).to(agent_pos.dtype).mean(-1) - beta * nearest.mean(-1) / (world_size / 2)
    r = team.unsqueeze(-1) - gamma * agent_collisions.to(agent_pos.dtype)
    return torch.where(alive, r, torch.zeros_like(r))
