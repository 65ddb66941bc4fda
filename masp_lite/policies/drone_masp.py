"""MASP on drones: the trained Goal Matcher and Gaussian executor flying the quadrotor world.

The method table (:data:`masp_lite.policies.METHODS`) gives ``masp`` on a drone world this
class (weights with ``action="throttle"``, the paper's motor commands); ``masp-velocity`` is
the variant whose executor asks the geometric controller for a velocity (weights with
``action="velocity"``), kept apart so a record never mixes them. Every global step the Goal
Matcher gives the flying drones distinct goals (the assignment with the least summed squared
``-log`` score, :func:`~masp_lite.nets.decoding.joint_argmax`), or the Hungarian assignment with weights
trained with ``goal_matcher="hungarian"``; every step the executor's action is its
Gaussian's mean (``deterministic``, the default) or a sample, clipped to [−1, 1]
(:mod:`masp_lite.nets.drones`).
"""
from __future__ import annotations

import torch

from ..algos.assignment import hungarian_goals
from ..nets.decoding import joint_argmax
from ..planners.geometric import motor_commands, velocity_controller
from ..weights import load_weights, method_checkpoint
from . import learned_methods

__all__ = ["DroneMASPPolicy", "DRONE_METHODS"]

_LEARNED = learned_methods("drone")
#: A view of the method table: the learned drone methods -> their executor's ``NetConfig.action``.
DRONE_METHODS = {m: e["nets"]["action"] for m, e in _LEARNED.items()}


class DroneMASPPolicy:
    """Trained MASP for drone worlds (``method`` ``masp``, or ``masp-velocity``: the networks' ``action``
    is the table's).

    ``checkpoint``: a weights file (default: the shipped ones for ``masp``, the packaged seed-0
    weights for ``masp-velocity``, :func:`masp_lite.weights.method_checkpoint`).
    ``seed`` seeds the group division and, with ``deterministic=False``, the samples;
    ``global_step`` overrides the weights' Goal Matcher period.
    """

    def __init__(self, world, checkpoint: str | None = None, seed: int = 0, global_step: int | None = None,
                 deterministic: bool = True, any_scenario: bool = False, method: str = "masp"):
        if method not in DRONE_METHODS:
            raise ValueError(f"method: expected one of {sorted(DRONE_METHODS)}, got {method!r}")
        if getattr(world.scenario, "kind", None) != "drone":
            raise ValueError(f"{type(self).__name__}: expected a drone world (drone-* scenario)")
        self.method, action, weights = method, DRONE_METHODS[method], _LEARNED[method]["weights"]
        if isinstance(checkpoint, torch.nn.Module):  # networks in memory (:meth:`from_nets`): taken as they are
            nets, meta, action = checkpoint, {}, checkpoint.config.action
        else:
            if checkpoint is None and weights != "shipped":
                checkpoint = method_checkpoint(method, world.scenario, weights)
            nets, meta = load_weights(checkpoint, scenario=world.scenario, any_scenario=any_scenario)
        if nets.config.action != action:
            raise ValueError(f"{method}: the checkpoint's executor outputs {nets.config.action!r} actions, "
                             f"expected {action!r}"
                             + ("; use --method masp-velocity" if nets.config.action == "velocity" else
                                "; use --method masp" if nets.config.action == "throttle" else ""))
        gs = nets.arch["global_step"] if global_step is None else global_step
        if isinstance(gs, bool) or not isinstance(gs, int) or gs < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        self._setup(world, nets, meta, gs, seed, deterministic)

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
        return cls(world, checkpoint=nets, seed=seed, deterministic=deterministic,
                   method=next(m for m, a in DRONE_METHODS.items() if a == nets.config.action))

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
