"""PettingZoo face of the drone world: one episode as a ``pettingzoo.ParallelEnv``.

``masp_lite.envs.parallel_env(scenario, render_mode=None, **overrides)`` wraps a
:class:`~masp_lite.envs.drones.DroneWorld` with ``num_envs=1`` (physics, spawns, crashes
and team change are the world's).

========================  ===============================================================
Agents                    ``drone_0`` … ``drone_{N-1}``
Actions                   ``Box(-1, 1, (4,), float32)``: one command per motor (rotor model
                          in :mod:`masp_lite.envs.drone_model`; hover ≈ −0.41 each)
Observation               ``Box(-inf, inf, (10N + 9,), float32)`` per drone, see below
Reward                    simple_spread's, in 3-D, see below
Termination               a drone that crashed or was dropped, at the step it leaves
Truncation                every remaining drone at step ``horizon``
========================  ===============================================================

Observation of drone ``i`` ("relative" means *other minus self*; metres, m/s, rad/s):

=================================  ==========  =========================================
block                              length      notes
=================================  ==========  =========================================
own position, velocity             3 + 3       world frame, map centre at the origin
own attitude quaternion            4           (w, x, y, z)
own angular velocity               3           body frame
landmark positions, relative       3 N         landmark order
other drones' positions, relative  3 (N − 1)   drones j ≠ i in index order; 0 if gone
other drones' velocities, rel.     3 (N − 1)   same order; 0 if gone
other drones' alive flags          N − 1       1.0 flying, 0.0 crashed or dropped
=================================  ==========  =========================================

Reward (as the particle face): ``0.5 · (−Σ_l min_{alive j} |p_j − l|) + 0.5 · (−crash_i)``
where ``crash_i`` is ``info["agent_collisions"]`` of drone ``i`` at this step.

``reset(seed=None, options=None)`` takes the world's start-state options (``agent_pos``,
``agent_vel``, ``agent_quat``, ``agent_angvel``, ``landmark_pos`` — (N, 3) or (N, 4) —
and ``keep``); unknown keys only warn, because PettingZoo's ``parallel_api_test`` passes
one. There is no built-in render mode: 3-D playback is :mod:`masp_lite.viz.meshcat3d`.
"""
from __future__ import annotations

import gymnasium
import numpy as np
import torch

from ..checks import real_array
from ..drones import DroneWorld
from ..scenarios import Scenario
from .base import WorldParallelEnv

__all__ = ["DroneParallelEnv", "RESET_OPTIONS"]

RESET_OPTIONS = ("agent_pos", "agent_vel", "agent_quat", "agent_angvel", "landmark_pos", "keep")
LOCAL_RATIO = 0.5


class DroneParallelEnv(WorldParallelEnv):
    """One drone-world episode, drone by drone (see the module docstring for the spaces)."""

    reset_options = RESET_OPTIONS

    metadata = {"name": "masp_lite_drones", "render_modes": [], "render_fps": 62, "is_parallelizable": True}

    def __init__(self, scenario: str | Scenario = "drone-5", render_mode: str | None = None,
                 seed: int | None = None, **overrides):
        if render_mode is not None:
            raise ValueError(f"render_mode: expected None (3-D playback is masp_lite.viz.meshcat3d), "
                             f"got {render_mode!r}")
        self.render_mode = None
        self._world = DroneWorld(scenario, num_envs=1, seed=seed, **overrides)
        self.scenario = self._world.scenario
        N = self._world.num_agents
        self.possible_agents = [f"drone_{i}" for i in range(N)]
        self.agents = self.possible_agents[:]
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self._others = np.array([[j for j in range(N) if j != i] for i in range(N)], np.int64).reshape(N, N - 1)
        box = gymnasium.spaces.Box
        self.observation_spaces = {a: box(-np.inf, np.inf, (10 * N + 9,), np.float32) for a in self.possible_agents}
        self.action_spaces = {a: box(-1.0, 1.0, (4,), np.float32) for a in self.possible_agents}




    def reset(self, seed: int | None = None, options: dict | None = None):
        obs = self._world.reset(seed=seed, options=self._known_options(options))
        self.agents = self.possible_agents[:]
        o = self._observe(obs)
        return {a: o[self._index[a]] for a in self.agents}, self._infos(self.agents, obs)

    def step(self, actions: dict):
        if not self.agents:
            raise ValueError("step: the episode is over (no drones left); expected reset() before step()")
        if not isinstance(actions, dict) or set(actions) != set(self.agents):
            raise ValueError(f"step: expected a dict with one action for each live drone {self.agents}")
        full = np.full((1, self._world.num_agents, 4), -1.0)  # drones that left: motors off (ignored anyway)
        for name, a in actions.items():
            value = real_array(a, f"step: action of {name!r}")
            if value.shape != (4,):
                raise ValueError(f"step: action of {name!r}: expected 4 motor commands, got shape {value.shape}")
            full[0, self._index[name]] = value
        obs, info = self._world.step(full)  # the world validates the range
        o, alive = self._observe(obs), info["alive"][0].numpy()
        rewards = self._rewards(obs, info)
        acting = self.agents
        over = bool(info["done"][0])
        terminations = {a: not alive[self._index[a]] for a in acting}
        truncations = {a: over and alive[self._index[a]] for a in acting}
        self.agents = [] if over else [a for a in acting if alive[self._index[a]]]
        return ({a: o[self._index[a]] for a in acting}, {a: float(rewards[self._index[a]]) for a in acting},
                terminations, {a: bool(v) for a, v in truncations.items()}, self._infos(acting, obs, info))

    def _observe(self, obs) -> np.ndarray:
        pos, vel = obs["agent_pos"][0].numpy(), obs["agent_vel"][0].numpy()
        quat, angvel = obs["agent_quat"][0].numpy(), obs["agent_angvel"][0].numpy()
        lms, alive = obs["landmark_pos"][0].numpy(), obs["alive"][0].numpy()
        N, others = len(pos), self._others
        seen = alive[others][..., None]
        blocks = [pos, vel, quat, angvel, (lms[None] - pos[:, None]).reshape(N, -1),
                  np.where(seen, pos[others] - pos[:, None], 0.0).reshape(N, -1),
                  np.where(seen, vel[others] - vel[:, None], 0.0).reshape(N, -1), alive[others].astype(np.float32)]
        return np.concatenate(blocks, axis=1).astype(np.float32)

    def _rewards(self, obs, info) -> np.ndarray:
        alive = obs["alive"][0]
        dist = torch.cdist(obs["agent_pos"][0].double(), obs["landmark_pos"][0].double())
        nearest = dist.masked_fill(~alive[:, None], float("inf")).min(dim=0).values
        team = -float(nearest.clamp(max=1e6).sum())
        return (1 - LOCAL_RATIO) * team - LOCAL_RATIO * info["agent_collisions"][0].double().numpy()

    def _infos(self, names, obs, info=None) -> dict[str, dict]:
        crashes = np.zeros(len(self.possible_agents), np.int64) if info is None else info["agent_collisions"][0].numpy()
        covered = int(obs["covered"][0].sum())
        return {a: {"collisions": int(crashes[self._index[a]]), "covered_landmarks": covered} for a in names}

    def render(self):
        gymnasium.logger.warn("drones have no render mode here; use masp_lite.viz.meshcat3d for 3-D playback")

    def close(self):
        pass
