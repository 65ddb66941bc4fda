"""Starting a world from a given state: the checks of ``reset(options=...)``.

The PettingZoo face, the tests, the exercises and the side-by-side comparisons start
episodes from given positions (``reset(options={"agent_pos": ..., ...})``); training and
evaluation draw every start at random and never load this module. Each world says which
options it takes (``reset_options``: name -> size of the last axis) and within which
bounds (``_option_bounds``); :func:`start_state` checks names, shapes, values and bounds
once for every world, and :func:`check_particle_start` what the particle world refuses of
a given start (drawn starts are apart by construction).
"""
from __future__ import annotations

import numpy as np
import torch

from .checks import real_array

__all__ = ["start_state", "bounds_text", "check_particle_start"]


def start_state(world, options: dict, n: int) -> dict[str, np.ndarray]:
    """Validated start-state options of ``world`` for ``n`` episodes, float64 arrays (n, N, d).

    Each may be given for one episode, (N, d), or per episode, (n, N, d); ``keep`` is
    checked by the world's ``_team_mask``; any other key is one clear error."""
    unknown = sorted(set(options) - set(world.reset_options) - {"keep"})
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; expected some of "
                         f"{sorted(world.reset_options) + ['keep']}")
    given = {}
    for name, d in world.reset_options.items():
        if name not in options:
            continue
        value = options[name]
        shape = (world.num_obstacles if name == "obstacle_pos" else world.num_agents, d)
        a = real_array(value, f"reset option {name!r}")
        if a.shape == shape:
            a = np.broadcast_to(a, (n, *shape))
        if a.shape != (n, *shape):
            raise ValueError(f"reset option {name!r}: expected shape {shape} or {(n, *shape)}, got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"reset option {name!r}: expected finite values")
        low, high = world._option_bounds(name)
        bad = (a < low) | (a > high)
        if bad.any():
            raise ValueError(f"reset option {name!r}: expected values in {bounds_text(low, high)}, "
                             f"got {a[bad].flat[0]:g}")
        given[name] = a.copy()
    return given


def bounds_text(low, high) -> str:
    """Per-coordinate bounds in words, e.g. ``"[-8, 8]"`` or ``"[-8, 8] x [-8, 8] x [0, 3]"``."""
    low, high = np.broadcast_arrays(np.atleast_1d(low), np.atleast_1d(high))
    return " x ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(low, high))


def check_particle_start(scenario, agents, obst, lms) -> None:
    """Refuse a particle start state that MPE's physics cannot run or that no episode can solve.

    Given agents may overlap each other or an obstacle, as MPE allows: the contact force
    pushes them apart in the first steps (and counts as a collision). What is refused:
    two agents, or an agent and an obstacle, at the very same point (the contact force has
    no direction there), overlapping obstacles, and a landmark inside an obstacle.
    ``agents``, ``obst``, ``lms``: (n, N, 2), (n, K, 2), (n, N, 2) tensors.
    """

    def closest(a, b, same):
        d = (a[:, :, None] - b[:, None]).norm(dim=-1)
        if same:
            d = d + torch.eye(a.shape[1], dtype=d.dtype) * 1e9
        return float(d.min()) if d.numel() else float("inf")

    if closest(agents, agents, True) == 0.0:
        raise ValueError("reset options: two agents at the same point; expected distinct agent positions "
                         "(agents may overlap: contact pushes them apart)")
    if closest(agents, obst, False) == 0.0:
        raise ValueError("reset options: an agent at the centre of an obstacle; expected it elsewhere "
                         "(an agent may overlap an obstacle: contact pushes it out)")
    if closest(obst, obst, True) < 2 * scenario.obstacle_radius:
        raise ValueError("reset options: obstacles overlap; expected centres at least "
                         f"{2 * scenario.obstacle_radius:g} m apart")
    if closest(lms, obst, False) < scenario.landmark_radius + scenario.obstacle_radius:
        raise ValueError("reset options: a landmark lies inside an obstacle; expected centres at least "
                         f"{scenario.landmark_radius + scenario.obstacle_radius:g} m apart")
