"""The one way to build a world: ``make`` (batched) and ``parallel_env`` (PettingZoo).

Both look the scenario up once (:func:`~masp_lite.envs.scenarios.get_scenario`: presets,
overrides, validation) and pick the world of its ``kind``. The drone world and the
PettingZoo faces are imported only when asked for, so a particle-world user needs
neither MuJoCo nor PettingZoo loaded.
"""
from __future__ import annotations

import torch

from .particle import ParticleWorld
from .scenarios import Scenario, get_scenario

__all__ = ["make", "parallel_env"]


def make(scenario: str | Scenario, num_envs: int = 1, device: str | torch.device = "cpu",
         seed: int | None = None, threads: int = 1, **overrides):
    """Batched world for ``scenario`` (particle or drone presets; see :mod:`.scenarios`).

    ``threads``: the threads ``mujoco.batch`` steps drone worlds on (particle worlds compute
    on torch's threads and ignore it)."""
    sc = get_scenario(scenario, **overrides)
    if sc.kind == "drone":
        from .drones import DroneWorld  # MuJoCo is only needed for drones
        return DroneWorld(sc, num_envs=num_envs, device=device, seed=seed, threads=threads)
    return ParticleWorld(sc, num_envs=num_envs, device=device, seed=seed)


def parallel_env(scenario: str | Scenario = "mpe-5", render_mode: str | None = None, **overrides):
    """A PettingZoo ``ParallelEnv`` over one episode of ``scenario`` (any preset)."""
    sc = get_scenario(scenario, **overrides)
    if sc.kind == "drone":
        from .pettingzoo.drones import DroneParallelEnv
        return DroneParallelEnv(sc, render_mode=render_mode)
    from .pettingzoo.particle import ParticleParallelEnv
    return ParticleParallelEnv(sc, render_mode=render_mode)
