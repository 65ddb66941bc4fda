"""``h-greedy`` on drones: Hungarian goals in 3-D, straight flights under the geometric controller.

The paper's "(H)" goal assignment with straight-line motion, for the drone world:
Hungarian assignment of drones to landmarks in 3-D
(:func:`masp_lite.algos.assignment.hungarian`), then each drone flies straight to its
landmark under :class:`~masp_lite.planners.geometric.LeeController`. It re-assigns when
the team changes (a crash, or the drop after ``change_step``); in varying-team
scenarios, where success counts landmarks ever reached, it also re-assigns the free
drones to landmarks not yet reached. ``h-greedy`` hands a drone world to this class.

With ``goals="masp"`` (or ``"masp-velocity"``) the goals are those of MASP's trained Goal
Matcher instead, decoded every one of its global steps (:mod:`masp_lite.policies.goal_sources`):
MASP's upper level above the straight flight, one half of the two-level split of chapter 11.
"""
from __future__ import annotations

import torch

from ..algos.assignment import hungarian
from ..planners.geometric import LeeController
from .goal_sources import goal_source

__all__ = ["DroneHungarianGreedy"]


class DroneHungarianGreedy:
    """h-greedy for drone worlds: Hungarian drones→landmarks in 3-D, fly straight, hover there.

    Options: ``max_speed`` (m/s, default 4), ``replan_every`` (steps between re-assignments
    in varying-team scenarios, default 15), ``goals`` (``"hungarian"``, the default, or a
    Goal Matcher's: :data:`~masp_lite.policies.goal_sources.GOAL_SOURCES`; it then re-assigns
    every global step of that Goal Matcher, ``replan_every`` unused), ``checkpoint`` (that
    method's weights; default its shipped ones), and the controller's gains (see
    :class:`LeeController`). The velocity gain defaults to ``kv = 4`` instead of
    OmniDrones' 2.2: with ``kx = 4`` the position loop is then critically damped, so a drone
    stops on its landmark instead of overshooting into a neighbour or out of the map
    (on drone-20 this lifts h-greedy's success rate from ≈0.96 to ≈0.98).
    """

    def __init__(self, world, max_speed: float = 4.0, replan_every: int = 15, kv: float = 4.0,
                 goals: str = "hungarian", checkpoint: str | None = None, **gains):
        if getattr(world.scenario, "kind", None) != "drone":
            raise ValueError("DroneHungarianGreedy: expected a drone world (drone-* scenario)")
        if not isinstance(replan_every, int) or replan_every < 1:
            raise ValueError(f"replan_every: expected a positive int, got {replan_every!r}")
        self.world, self.replan_every = world, replan_every
        self.controller = LeeController(kv=kv, max_speed=max_speed, **gains)
        self.source = goal_source(goals, world, checkpoint)   # None: Hungarian goals
        self.goal = None

    def _fly_to(self, idx, obs, due=None):
        """Set the target of every drone (of the worlds ``due``) to landmark ``idx``; ``-1``: stay put."""
        lms = obs["landmark_pos"]
        idx = idx.to(lms.device)
        target = torch.gather(lms, 1, idx.clamp_min(0).unsqueeze(-1).expand(-1, -1, 3))
        goal = torch.where((idx >= 0).unsqueeze(-1), target, obs["agent_pos"])
        self.goal = goal if due is None or self.goal is None else torch.where(due[:, None, None], goal, self.goal)
        self.goal_index = idx if due is None or self.goal_index is None else \
            torch.where(due[:, None], idx, self.goal_index)

    def _assign(self, obs):
        alive, lms = obs["alive"], obs["landmark_pos"]
        goal_mask = torch.ones_like(obs["reached"])
        if self.world.scenario.varying:  # success = ever reached: go where nobody has been
            free = ~obs["reached"]
            goal_mask = torch.where(free.any(1, keepdim=True), free, goal_mask)
        self._fly_to(hungarian(obs["agent_pos"], lms, agent_mask=alive, goal_mask=goal_mask), obs)
        self._alive = alive.clone()

    def reset(self, obs) -> None:
        self._steps = 0
        self.goal = self.goal_index = None
        if self.source is not None:
            self.source.reset(obs)
            self._fly_to(self.source(obs), obs)
        else:
            self._assign(obs)

    def act(self, obs) -> torch.Tensor:
        if self.goal is None:
            self.reset(obs)
        self._steps += 1
        if self.source is not None:  # the Goal Matcher's goals, every one of its global steps
            due = (obs["t"] % self.source.global_step == 0).to(self.goal.device)
            if bool(due.any()):
                self._fly_to(self.source(obs), obs, due)
        elif not torch.equal(obs["alive"], self._alive) or \
                (self.world.scenario.varying and self._steps % self.replan_every == 0):
            self._assign(obs)
        return self.controller(obs["agent_pos"], obs["agent_vel"], obs["agent_quat"], obs["agent_angvel"],
                               target_pos=self.goal)
