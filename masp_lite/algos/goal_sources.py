"""The goal sources of the ablations and baselines that train no Goal Matcher (``NetConfig.goal_matcher``).

MASP's trainer (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) samples goals from its Goal
Matcher; these sources stand in for it, beside the paper's path:

* ``random`` ("MASP w. RG"): distinct random goals when the episode starts, redrawn only when
  the team changes;
* ``hungarian`` (``h-mappo``, or a drone curriculum stage): the Hungarian assignment every
  global step;
* ``none`` (``mappo``, ``darl1n``): no goals; the executor sees every landmark.

With a varying team, landmarks already reached count for SR, so goals are drawn among the rest.
"""
from __future__ import annotations

import torch

from ..nets.decoding import random_goals
from .team import hungarian_goals

__all__ = ["scripted_goals"]


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
