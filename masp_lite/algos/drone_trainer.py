"""MASP training on the quadrotor world: the particle trainer's loop with Gaussian motor commands.

:class:`DroneMASPTrainer` is :class:`~masp_lite.algos.masp_trainer.MASPTrainer` (same
storage, GAE, PPO on both levels, checkpoints and resume) with a drone rollout:

1. every ``global_step`` steps the Goal Matcher draws distinct goals for the flying drones
   (``goal_matcher="graph"``, trained on R_GM against the 3-D Hungarian assignment) or takes
   the Hungarian assignment (``goal_matcher="hungarian"``: an executor-only curriculum stage);
2. the executor (:class:`~masp_lite.nets.drones.DroneExecutor`) samples a Gaussian action per
   drone; the clipped sample is 4 motor commands (``action="throttle"``, the paper's) or a
   velocity set-point that :class:`~masp_lite.planners.geometric.LeeController` turns into
   motor commands (``action="velocity"``);
3. R_CAE (eq. 5, :func:`~masp_lite.algos.rewards.executor_reward`) in 3-D, where a contact,
   a floor touch or leaving the flight volume is the collision (the world's
   ``agent_collisions``), and **a crash ends the drone**: it is out of the episode (the
   paper: "collisions directly lead to crashes and task failures").

**The crash charge.** A crashed drone earns nothing afterwards, so with a distance
*penalty* every step, crashing early would save penalties. To make a crash never pay, the
step a drone crashes it is also charged the distance penalty of its crash site for every
step left in the episode: ``R = R_CAE − β · (T − t − 1) · dist / (world_size / 2)``. A drone
that hovers where it is does at least as well, so flying on always beats crashing.
"""
from __future__ import annotations

import torch

from ..nets.decoding import sequential_sample
from ..nets.drones import DRONE_SPEED, gaussian_log_prob
from ..planners.geometric import LeeController
from .assignment import hungarian_goals
from .mappo import RolloutStorage
from .masp_trainer import MASPTrainer
from .rewards import executor_reward, goal_matcher_reward

__all__ = ["DroneMASPTrainer", "DRONE_OBS_KEYS", "crash_charge", "motor_commands", "velocity_controller"]

DRONE_OBS_KEYS = ("agent_pos", "agent_vel", "landmark_pos", "alive", "covered", "reached", "t")


def crash_charge(dist: torch.Tensor, crashed: torch.Tensor, steps_left: int, world_size: float,
                 beta: float = 1.0) -> torch.Tensor:
    """(B, N): ``β · steps_left · dist / (world_size / 2)`` for the drones that ``crashed`` this step, else 0."""
    return torch.where(crashed, beta * steps_left * dist / (world_size / 2), torch.zeros_like(dist))


def velocity_controller() -> LeeController:
    """The geometric controller that flies ``velocity`` actions (velocity gain 4, speed capped at ``DRONE_SPEED``)."""
    return LeeController(kv=4.0, max_speed=DRONE_SPEED)


def motor_commands(actions: torch.Tensor, obs: dict, controller: LeeController | None = None) -> torch.Tensor:
    """The world's motor commands (B, N, 4) for executor actions ``actions``, clipped to [−1, 1] first.

    Without ``controller`` (``action="throttle"``) the clipped actions are the commands; with one
    (``action="velocity"``, :func:`velocity_controller`) the clipped action × ``DRONE_SPEED`` is the
    velocity set-point the controller flies from the drone's own position.
    """
    a = actions.clamp(-1.0, 1.0)
    if controller is None:
        return a
    pos = obs["agent_pos"]
    return controller(pos, obs["agent_vel"], obs["agent_quat"], obs["agent_angvel"], target_pos=pos,
                      target_vel=a * DRONE_SPEED)


class DroneMASPTrainer(MASPTrainer):
    """MASP on a drone scenario (``NetConfig.action`` ``throttle`` or ``velocity``)."""

    distribution = "gaussian"

    def __init__(self, scenario, cfg, seed: int = 0, overrides: dict | None = None):
        super().__init__(scenario, cfg, seed, overrides)
        if self.random_goals or self.goal_free:
            raise ValueError(f"drone training: expected goal_matcher 'graph' or 'hungarian', got "
                             f"{cfg.net.goal_matcher!r}")
        self.controller = velocity_controller() if cfg.net.action == "velocity" else None

    @torch.inference_mode()
    def collect(self):
        w, n, cfg, g = self.world, self.nets, self.cfg, self.generator
        obs = w.reset()
        gm, cae = RolloutStorage(), RolloutStorage()
        goals = None
        cov, col = [obs["covered"].all(-1)], []
        B, N, T, rc = w.num_envs, w.num_agents, self.horizon, cfg.reward
        for t in range(T):
            snap = {k: obs[k].clone() for k in DRONE_OBS_KEYS}
            if t % cfg.net.global_step == 0:
                if self.hungarian_goals:
                    goals = hungarian_goals(obs["agent_pos"], obs["landmark_pos"], obs["alive"])
                else:
                    logits = n.gm_logits(obs, self.scale)
                    goals, logp, rank = sequential_sample(logits, obs["alive"], g)
                    v = n.gm_value(obs, self.scale, T)
                    r = goal_matcher_reward(obs["agent_pos"], obs["landmark_pos"], goals, obs["alive"])
                    gm.add(**snap, actions=goals, rank=rank, logp=logp, values=v, rewards=r,
                           mask=obs["alive"].clone())
            perm = torch.rand(B, N, generator=g).argsort(-1)
            inputs = n.cae_inputs(obs, goals, perm)
            (mean, log_std), v = n.cae_forward(inputs, obs, T)
            actions = mean + log_std.exp() * torch.randn(mean.shape, generator=g, dtype=mean.dtype)
            logp = gaussian_log_prob(mean, log_std, actions)
            alive = obs["alive"].clone()
            obs, info = w.step(motor_commands(actions, obs, self.controller))
            goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand(B, N, 3))
            r = executor_reward(obs["agent_pos"], goal_pos, info["agent_collisions"], alive, self.reach,
                                w.scenario.world_size, rc.bonus_coef, rc.distance_coef, rc.collision_coef)
            crashed = alive & ~obs["alive"]
            if bool(crashed.any()):
                dist = (goal_pos - obs["agent_pos"]).norm(dim=-1)
                r = r - crash_charge(dist, crashed, T - t - 1, w.scenario.world_size, rc.distance_coef)
            cae.add(**snap, pair=inputs[0], groups=inputs[1], goal_f=inputs[3], state_f=inputs[4],
                    actions=actions, logp=logp, values=v, rewards=r, mask=alive)
            cov.append(info["covered"].all(-1))
            col.append(info["collisions"])
        self.env_steps += T * B
        solved = torch.stack(cov, 1)
        first = torch.where(solved, torch.arange(T + 1), T).min(1).values
        stats = {"sr": float(obs["covered"].float().mean()), "steps": float(first.float().mean()),
                 "cr": float(torch.stack(col, 1).float().mean())}
        gm_data = self._advantages(gm.stacked(), self.gm_norm, cfg.ppo.gm_gamma) if self.gm_trained else None
        return gm_data, \
            self._advantages(cae.stacked(), self.cae_norm, cfg.ppo.gamma, update=cfg.run.train_executor), stats

    def _gm_eval(self, mb):
        return super()._gm_eval({**mb, "obstacle_pos": None})

    def _cae_eval(self, mb):
        obs = {k: mb[k] for k in DRONE_OBS_KEYS}
        inputs = (mb["pair"], mb["groups"], mb["alive"], mb["goal_f"], mb["state_f"])
        return self.nets.cae_forward(inputs, obs, self.horizon)
