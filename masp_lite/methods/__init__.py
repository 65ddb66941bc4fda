"""Registry of navigation methods: name -> policy factory.

A *policy* drives a batched world. It implements

* ``reset(obs) -> None`` — called after ``world.reset()`` with its observation;
* ``act(obs) -> actions`` — the actions for ``world.step``: an integer tensor (B, N) of
  action ids for the particle world, a float tensor (B, N, 4) of motor commands for drones.

Only ``act`` is timed as *decision time* by :mod:`masp_lite.eval`. Factories are named by
``"module:attribute"`` strings and imported on first use, so a method's dependencies
load only when it is asked for. A factory is called as ``factory(world, **options)``.
"""
from __future__ import annotations

import importlib

__all__ = ["METHODS", "make_policy", "method_names"]

METHODS: dict[str, str] = {
    "random": "masp_lite.methods.reference:RandomPolicy",
    "h-greedy": "masp_lite.methods.reference:HungarianGreedy",
    "h-orca": "masp_lite.planners.methods:HOrca",
    "h-rrtstar": "masp_lite.planners.methods:HRRTStar",
    "h-voronoi": "masp_lite.planners.methods:HVoronoi",
    "masp": "masp_lite.nets.policies:MASPPolicy",
}


def method_names() -> list[str]:
    return sorted(METHODS)


def make_policy(name: str, world, **options):
    """Build the policy called ``name`` for ``world`` (options are method-specific)."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {method_names()}")
    module_name, attr = METHODS[name].split(":")
    factory = getattr(importlib.import_module(module_name), attr)
    return factory(world, **options)
