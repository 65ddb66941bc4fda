"""Worlds: the batched particle world, the MuJoCo drone world and their PettingZoo faces.

``make(scenario, num_envs=1, device="cpu", seed=None, **overrides)`` builds a batched world;
``parallel_env(scenario, render_mode=None, **overrides)`` a PettingZoo ``ParallelEnv`` over
one episode.
"""
from .particle import ACTION_DIRECTIONS, NUM_ACTIONS, PHYSICS, ParticleWorld, make
from .scenarios import OVERRIDES, SCENARIOS, Scenario, get_scenario, scenario_names

__all__ = ["make", "parallel_env", "ParticleWorld", "Scenario", "SCENARIOS", "OVERRIDES",
           "get_scenario", "scenario_names", "PHYSICS", "ACTION_DIRECTIONS", "NUM_ACTIONS"]


def parallel_env(scenario: str = "mpe-5", render_mode: str | None = None, **overrides):
    """PettingZoo ``ParallelEnv`` over one episode of ``scenario``."""
    from .pettingzoo import parallel_env as _parallel_env  # pettingzoo imported on demand
    return _parallel_env(scenario, render_mode=render_mode, **overrides)
