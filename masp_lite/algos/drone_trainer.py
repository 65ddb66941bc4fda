"""MASP training on the quadrotor world: the particle trainer with a drone action step.

:class:`DroneMASPTrainer` is :class:`~masp_lite.algos.masp_trainer.MASPTrainer` (the same
rollout loop, storage, GAE, PPO on both levels, checkpoints and resume); only its hooks
differ — the networks (:class:`~masp_lite.nets.drones.DroneNets`), the action step and the
crash charge on R_CAE:

1. every ``global_step`` steps the Goal Matcher draws distinct goals for the flying drones
   (``goal_matcher="graph"``, trained on R_GM against the 3-D Hungarian assignment) or takes
   the Hungarian assignment (``goal_matcher="hungarian"``: MASP's executor-only curriculum
   stage, and ``h-mappo``); the RL baselines' other goal sources and executor views are the
   particle world's settings (:mod:`masp_lite.nets.variants`), in 3-D;
2. the executor (:class:`~masp_lite.nets.drones.DroneExecutor`) samples a Gaussian action per
   drone; the clipped sample is 4 motor commands (``action="throttle"``, the paper's) or a
   velocity set-point that :class:`~masp_lite.planners.geometric.LeeController` turns into
   motor commands (``action="velocity"``; :func:`~masp_lite.planners.geometric.motor_commands`);
3. R_CAE (eq. 5, :func:`~masp_lite.algos.rewards.executor_reward`) in 3-D, where a contact,
   a floor touch or leaving the flight volume is the collision (the world's
   ``agent_collisions``), and **a crash ends the drone**: it is out of the episode (the
   paper: "collisions directly lead to crashes and task failures").

**The crash charge.** A crashed drone earns nothing afterwards, so with a distance
*penalty* every step, crashing early would save penalties. To make a crash never pay, the
step a drone crashes it is also charged the distance penalty of its crash site for every
step left in the episode: ``R = R_CAE − β · (T − t − 1) · dist / (world_size / 2)``. A drone
that hovers where it is does at least as well, so flying on always beats crashing. Without
goals (``mappo``, ``darl1n``) ``dist`` is the coverage reward's distance term (the mean over
landmarks of the nearest drone's distance, the crashed drone still counted) at the crash.
"""
from __future__ import annotations

import torch

from ..nets.drones import DroneNets, gaussian_entropy, gaussian_log_prob
from ..planners.geometric import motor_commands, velocity_controller
from .masp_trainer import MASPTrainer

__all__ = ["DroneMASPTrainer", "DRONE_OBS_KEYS", "crash_charge", "gaussian", "motor_commands", "velocity_controller"]

DRONE_OBS_KEYS = ("agent_pos", "agent_vel", "landmark_pos", "alive", "covered", "reached", "t")


def gaussian(out, actions):
    """``(log-probabilities, entropies)`` of ``actions`` under the executor's Gaussian ``out = (mean, log_std)``."""
    mean, log_std = out
    logp = gaussian_log_prob(mean, log_std, actions)
    return logp, gaussian_entropy(log_std, logp.shape)


def crash_charge(dist: torch.Tensor, crashed: torch.Tensor, steps_left: int, world_size: float,
                 beta: float = 1.0) -> torch.Tensor:
    """(B, N): ``β · steps_left · dist / (world_size / 2)`` for the drones that ``crashed`` this step, else 0."""
    return torch.where(crashed, beta * steps_left * dist / (world_size / 2), torch.zeros_like(dist))


class DroneMASPTrainer(MASPTrainer):
    """MASP on a drone scenario (``NetConfig.action`` ``throttle`` or ``velocity``)."""

    distribution = staticmethod(gaussian)
    nets_class = DroneNets
    obs_keys = DRONE_OBS_KEYS

    def __init__(self, scenario, cfg, seed: int = 0, overrides: dict | None = None):
        super().__init__(scenario, cfg, seed, overrides)
        self.controller = velocity_controller() if cfg.net.action == "velocity" else None

    def act(self, out, obs):
        """A Gaussian sample per drone (stored unclipped), flown as clipped motor commands or velocities."""
        mean, log_std = out
        actions = mean + log_std.exp() * torch.randn(mean.shape, generator=self.generator, dtype=mean.dtype)
        return actions, gaussian_log_prob(mean, log_std, actions), motor_commands(actions, obs, self.controller)

    def executor_reward(self, obs, goals, info, alive, t):
        """R_CAE in 3-D (the goal-free baselines' coverage reward), minus :func:`crash_charge` for the drones
        that crashed this step."""
        r = super().executor_reward(obs, goals, info, alive, t)
        crashed = alive & ~obs["alive"]
        if bool(crashed.any()):
            if goals is None:  # the team's distance term: mean over landmarks of the nearest drone, crashed ones too
                d = torch.cdist(obs["landmark_pos"], obs["agent_pos"]).masked_fill(~alive.unsqueeze(1), float("inf"))
                dist = d.min(-1).values.mean(-1, keepdim=True).expand_as(crashed)
            else:
                goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(obs["agent_pos"]))
                dist = (goal_pos - obs["agent_pos"]).norm(dim=-1)
            r = r - crash_charge(dist, crashed, self.horizon - t - 1, self.world.scenario.world_size,
                                 self.cfg.reward.distance_coef)
        return r
