"""MASP on drones: the trained Goal Matcher and Gaussian executor flying the quadrotor world.

The particle policy (:class:`~masp_lite.policies.masp.MASPPolicy`) with the drone's action:
the goals are chosen the same way every global step (by default the assignment of distinct
goals with the least summed squared ``-log`` score, :func:`~masp_lite.nets.decoding.joint_argmax`,
or the Hungarian assignment with weights trained with ``goal_matcher="hungarian"``), and every
step the executor's action is its Gaussian's mean (``deterministic``, the default) or a sample,
clipped to [−1, 1] (:mod:`masp_lite.nets.drones`). ``decode="hungarian"`` gives the executor
the Hungarian goals instead, every global step: with the planners' ``goals="masp"``
(:mod:`masp_lite.policies.goal_sources`) it splits a gap in Steps between the two levels.

The method table (:data:`masp_lite.policies.METHODS`) gives ``masp`` on a drone world this
class (weights with ``action="throttle"``, the paper's motor commands); ``masp-velocity`` is
the variant whose executor asks the geometric controller for a velocity (weights with
``action="velocity"``), kept apart so a record never mixes them; the RL baselines (``h-mappo``,
``htamp``, ``mage-x``, ``mappo``, ``darl1n``) fly motor commands with their own goal sources
and executor views, as on particles.
"""
from __future__ import annotations

import torch

from ..planners.geometric import motor_commands, velocity_controller
from . import learned_methods
from .masp import MASPPolicy

__all__ = ["DroneMASPPolicy", "DRONE_METHODS"]

#: A view of the method table: the learned drone methods -> their executor's ``NetConfig.action``.
DRONE_METHODS = {m: e["nets"]["action"] for m, e in learned_methods("drone").items()}


class DroneMASPPolicy(MASPPolicy):
    """Trained networks for drone worlds (``method``: ``masp``, ``masp-velocity`` or an RL baseline of the table).

    ``checkpoint``: a weights file (default: the shipped ones for ``masp``, the packaged seed-0
    weights for the others, :func:`masp_lite.weights.method_checkpoint`). The other options are
    :class:`~masp_lite.policies.masp.MASPPolicy`'s.
    """

    kind = "drone"

    def _setup(self, global_step, deterministic, seed, decode):
        super()._setup(global_step, deterministic, seed, decode)
        self.controller = velocity_controller() if self.nets.config.action == "velocity" else None

    def action(self, out, obs) -> torch.Tensor:
        """Motor commands (B, N, 4) from the executor's Gaussian ``out = (mean, log_std)``."""
        mean, log_std = out
        a = mean if self.deterministic else \
            mean + log_std.exp() * torch.randn(mean.shape, generator=self.generator, dtype=mean.dtype)
        return motor_commands(a, obs, self.controller)
