"""MASP on drones: the trained Goal Matcher and Gaussian executor flying the quadrotor world.

``masp`` hands a drone world to :class:`DroneMASPPolicy` (weights with ``action="throttle"``,
the paper's motor commands); ``masp-velocity`` is the variant whose executor asks the
geometric controller for a velocity (weights with ``action="velocity"``), kept apart so a
record never mixes them. Every global step the Goal Matcher gives the flying drones
distinct goals (the most likely such assignment, :func:`~masp_lite.nets.decoding.joint_argmax`),
or the Hungarian assignment with weights trained with ``goal_matcher="hungarian"``; every
step the executor's action is its Gaussian's mean (``deterministic``, the default) or a
sample, clipped to [−1, 1] (:mod:`masp_lite.nets.drones`).
"""
from __future__ import annotations

from pathlib import Path

import torch

from ..algos.assignment import hungarian_goals
from ..nets.decoding import joint_argmax
from ..planners.geometric import motor_commands, velocity_controller
from ..weights import KEPT_DIR, base_scenario, load_weights

__all__ = ["DroneMASPPolicy", "DroneMASPVelocity", "DRONE_METHODS", "kept_checkpoint"]

#: The learned drone methods -> their executor's ``NetConfig.action``.
DRONE_METHODS = {"masp": "throttle", "masp-velocity": "velocity"}


def kept_checkpoint(method: str, scenario) -> Path:
    """Where a source checkout keeps the seed-0 drone weights of a learned variant that is not shipped."""
    return KEPT_DIR / method / f"{base_scenario(scenario)}-seed0.pt"


class DroneMASPPolicy:
    """Trained MASP for drone worlds (method ``masp``; the networks' ``action`` is ``ACTION``).

    ``checkpoint``: a weights file (default: the shipped ones for ``masp``, the kept seed-0
    weights ``results/training/METHOD/drone-N-seed0.pt`` of a source checkout for ``masp-velocity``).
    ``seed`` seeds the group division and, with ``deterministic=False``, the samples;
    ``global_step`` overrides the weights' Goal Matcher period.
    """

    METHOD, ACTION = "masp", "throttle"

    def __init__(self, world, checkpoint: str | None = None, seed: int = 0, global_step: int | None = None,
                 deterministic: bool = True, any_scenario: bool = False):
        if getattr(world.scenario, "kind", None) != "drone":
            raise ValueError(f"{type(self).__name__}: expected a drone world (drone-* scenario)")
        if checkpoint is None:
            checkpoint = self.kept(world.scenario)
        nets, meta = load_weights(checkpoint, scenario=world.scenario, any_scenario=any_scenario)
        if nets.config.action != self.ACTION:
            raise ValueError(f"{self.METHOD}: the checkpoint's executor outputs {nets.config.action!r} actions, "
                             f"expected {self.ACTION!r}"
                             + ("; use --method masp-velocity" if nets.config.action == "velocity" else
                                "; use --method masp" if nets.config.action == "throttle" else ""))
        gs = nets.arch["global_step"] if global_step is None else global_step
        if isinstance(gs, bool) or not isinstance(gs, int) or gs < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        self._setup(world, nets, meta, gs, seed, deterministic)

    def kept(self, scenario):
        """Default weights: the shipped ones for ``masp`` (None), the kept seed 0 for the others."""
        if self.METHOD == "masp":
            return None
        path = kept_checkpoint(self.METHOD, scenario)
        if not path.exists():
            raise ValueError(f"{self.METHOD}: no weights given and none kept for {scenario.name!r} (expected "
                             f"{path.relative_to(KEPT_DIR.parents[1])} of a source checkout); pass checkpoint=PATH")
        return path

    def _setup(self, world, nets, meta, global_step, seed, deterministic):
        self.world, self.nets, self.meta = world, nets.eval(), meta
        self.global_step, self.deterministic, self.seed = int(global_step), bool(deterministic), int(seed)
        self.scale = world.scenario.world_size / 2
        self.generator = torch.Generator().manual_seed(self.seed)
        self.controller = velocity_controller() if nets.config.action == "velocity" else None
        self.goals = None

    @classmethod
    def from_nets(cls, world, nets, seed: int = 0, deterministic: bool = True) -> "DroneMASPPolicy":
        """A policy around networks in memory (training's periodic evaluation)."""
        self = cls.__new__(cls)
        self._setup(world, nets, {}, nets.arch["global_step"], seed, deterministic)
        return self

    def reset(self, obs) -> None:
        self.goals = None

    @torch.inference_mode()
    def act(self, obs) -> torch.Tensor:
        alive = obs["alive"]
        due = obs["t"] % self.global_step == 0
        if self.goals is None or bool(due.any()):
            mask = None
            if self.world.scenario.varying:  # landmarks reached count for SR: pick among the rest
                mask = ~obs["reached"] | obs["reached"].all(-1, keepdim=True)
            if self.nets.config.goal_matcher == "hungarian":
                new = hungarian_goals(obs["agent_pos"], obs["landmark_pos"], alive, mask)
            else:
                new = joint_argmax(self.nets.gm_logits(obs, self.scale, mask), alive, mask)
            self.goals = new if self.goals is None else torch.where(due.unsqueeze(-1), new, self.goals)
        B, N = alive.shape
        perm = torch.rand(B, N, generator=self.generator).argsort(-1).to(alive.device)
        mean, log_std = self.nets.cae_logits(self.nets.cae_inputs(obs, self.goals, perm))
        a = mean if self.deterministic else \
            mean + log_std.exp() * torch.randn(mean.shape, generator=self.generator, dtype=mean.dtype)
        return motor_commands(a, obs, self.controller)


class DroneMASPVelocity(DroneMASPPolicy):
    """``masp-velocity``: MASP whose executor asks the geometric controller for a velocity set-point."""

    METHOD, ACTION = "masp-velocity", "velocity"
