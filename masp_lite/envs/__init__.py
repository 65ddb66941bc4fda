"""Worlds: the batched particle world, the MuJoCo drone world and their PettingZoo faces.

``make(scenario, num_envs=1, device="cpu", seed=None, **overrides)`` builds a batched world;
``parallel_env(scenario, render_mode=None, **overrides)`` a PettingZoo ``ParallelEnv`` over
one episode (:mod:`.registry`). Both worlds share :class:`~.base.BatchedWorld`.
"""
from .base import BatchedWorld
from .particle import ACTION_DIRECTIONS, NUM_ACTIONS, PHYSICS, ParticleWorld
from .registry import make, parallel_env
from .scenarios import MPE2_WORLD, OVERRIDES, PAPER_WORLD, SCENARIOS, Scenario, get_scenario, scenario_names, world_name

__all__ = ["make", "parallel_env", "BatchedWorld", "ParticleWorld", "Scenario", "SCENARIOS", "OVERRIDES",
           "get_scenario", "scenario_names", "world_name", "PAPER_WORLD", "MPE2_WORLD", "PHYSICS",
           "ACTION_DIRECTIONS", "NUM_ACTIONS"]
