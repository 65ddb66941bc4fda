"""Where a drone planner's goals come from: its own "(H)" assignment, or a trained MASP Goal Matcher.

MASP has two levels: the Goal Matcher picks a landmark per drone every global step, and the
executor flies there. The planners (``h-greedy``, ``h-orca``, ``h-rrtstar``, ``h-voronoi``) have
the same two levels, with the Hungarian assignment above and a flight controller below. Swapping
the upper levels tells which level costs the Steps. This module holds the planners' side:

* ``goals="hungarian"`` (the default): the planner's own assignment, unchanged (Hungarian in 3-D,
  under the scenario's team protocol; :class:`~masp_lite.algos.team.TeamAssignment`);
* ``goals="masp"`` or ``goals="masp-velocity"``: the goals that method's trained Goal Matcher
  decodes every global step (:meth:`MASPPolicy.choose_goals
  <masp_lite.policies.masp.MASPPolicy.choose_goals>`, the policy's own decoding, not a copy), from
  its default drone weights for the scenario or from ``checkpoint``. Only the Goal Matcher of
  those weights is used; the planner flies.

The other half of the split, MASP's executor flying Hungarian goals, is the policies'
``decode="hungarian"`` (:class:`~masp_lite.policies.masp.MASPPolicy`)::

    evaluate --method h-orca --scenario drone-20 --set goals=masp          # MASP's goals, ORCA's flight
    evaluate --method masp --scenario drone-20 --set decode=hungarian      # Hungarian goals, MASP's flight
"""
from __future__ import annotations

import torch

__all__ = ["GOAL_SOURCES", "GoalMatcherGoals", "goal_source"]

#: The goal sources a drone planner accepts: its own Hungarian assignment, or a learned method's Goal Matcher.
GOAL_SOURCES = ("hungarian", "masp", "masp-velocity")


class GoalMatcherGoals:
    """A trained Goal Matcher as a planner's goal source: ``source(obs)`` -> goal index per drone (B, N).

    ``method``: ``masp`` or ``masp-velocity`` (whose default drone weights load unless
    ``checkpoint`` names a weights file of that method). Goals are the policy's deterministic
    decoding (:func:`~masp_lite.nets.decoding.joint_argmax`: distinct goals for the alive drones);
    a drone that is no longer alive gets ``-1``, as in the Hungarian assignment. ``global_step``
    is the weights' Goal Matcher period, which the planner follows.
    """

    def __init__(self, world, method: str = "masp", checkpoint: str | None = None):
        from .drone_masp import DroneMASPPolicy  # the networks load only when this source is asked for
        self.policy = DroneMASPPolicy(world, checkpoint=checkpoint, method=method)
        self.method, self.global_step = method, self.policy.global_step

    def reset(self, obs) -> None:
        self.policy.reset(obs)

    def __call__(self, obs) -> torch.Tensor:
        goals = self.policy.choose_goals(obs)
        return torch.where(obs["alive"].to(goals.device), goals, torch.full_like(goals, -1))


def goal_source(name: str, world, checkpoint: str | None = None) -> GoalMatcherGoals | None:
    """The goal source called ``name`` (:data:`GOAL_SOURCES`) for ``world``; ``None`` for the planner's own.

    One clear error for an unknown name (listing the known ones), and for a ``checkpoint`` given
    with ``hungarian``, which has no weights."""
    if name not in GOAL_SOURCES:
        raise ValueError(f"goals: expected one of {list(GOAL_SOURCES)}, got {name!r}")
    if name == "hungarian":
        if checkpoint is not None:
            raise ValueError(f"checkpoint: the Hungarian goals take no weights; a checkpoint needs goals= one "
                             f"of {list(GOAL_SOURCES[1:])}")
        return None
    return GoalMatcherGoals(world, method=name, checkpoint=checkpoint)
