"""Harder training layouts: one landmark moved next to another landmark or an obstacle.

On mpe-5 both MASP and ``h-greedy`` lose their landmarks almost only where a landmark
has another landmark within 0.3 m or an obstacle centre within 0.25 m (see
``results/masp/README.md``, "Where the misses are"); uniform spawns make such layouts
about a third of all landmarks. :func:`harden_layouts` re-lays a chosen fraction of the
worlds just after a reset so that one landmark per chosen world sits in one of those two
places, and training sees them more often (``MAPPOConfig.hard_layouts``; the paper trains
on uniform spawns only, so this is off by default).

The moved landmark keeps the world's spawn rules: inside the map, clear of every obstacle
and every other landmark by the spawn gap; agents and obstacles are not moved. Draws come
from the trainer's generator, so the world's own spawn stream (and with it the layouts
of a run without the option) is unchanged. Written by hand because it is a few tensor
operations on the world's state.
"""
from __future__ import annotations

import math

import torch

__all__ = ["harden_layouts", "LANDMARK_NEAR", "OBSTACLE_NEAR"]

#: Farthest centre distance (m) of a moved landmark from its anchor landmark / obstacle.
LANDMARK_NEAR = 0.3
OBSTACLE_NEAR = 0.25

_SPAWN_GAP = 0.01
_TRIES = 16


def harden_layouts(world, fraction: float, generator: torch.Generator) -> torch.Tensor:
    """Move one landmark in about ``fraction`` of ``world``'s episodes; returns the ids moved.

    For each chosen episode: a random landmark ``j`` and an anchor, with equal odds another
    landmark (the new centre lies 2 r_l + gap … 0.3 m from it) or an obstacle (r_o + r_l +
    gap … 0.25 m from its centre; landmark anchors only when the world has no obstacles), at
    a uniform angle. Placements that leave the map or overlap another body are redrawn up
    to 16 times; an episode with no valid draw keeps its layout. The world is then reset to
    the new layout for those episodes (agents, obstacles and velocities as they are), so
    its observations, coverage and geometry are consistent.
    """
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"fraction: expected a number in [0, 1], got {fraction!r}")
    sc = world.scenario
    B, N, K = world.num_envs, world.num_agents, world.num_obstacles
    chosen = torch.nonzero(torch.rand(B, generator=generator) < fraction).flatten()
    if len(chosen) == 0 or (N < 2 and K == 0):
        return chosen[:0]
    n = len(chosen)
    lms = world.landmark_pos[chosen].to(torch.float64).clone()             # (n, N, 2)
    obst = world.obstacle_pos[chosen].to(torch.float64)                    # (n, K, 2)
    rl, ro = sc.landmark_radius, sc.obstacle_radius
    half = sc.world_size / 2 - rl
    j = (torch.rand(n, generator=generator) * N).long().clamp(max=N - 1)
    rows = torch.arange(n)
    placed = torch.zeros(n, dtype=torch.bool)
    for _ in range(_TRIES):
        use_obstacle = (torch.rand(n, generator=generator) < 0.5) if K else torch.zeros(n, dtype=torch.bool)
        if N < 2:
            use_obstacle[:] = True
        # anchor landmark: any other than j; anchor obstacle: any
        other = (j + 1 + (torch.rand(n, generator=generator) * (N - 1)).long().clamp(max=max(N - 2, 0))) % N
        k = (torch.rand(n, generator=generator) * max(K, 1)).long().clamp(max=max(K - 1, 0))
        anchor = torch.where(use_obstacle.unsqueeze(-1), obst[rows, k] if K else lms[rows, other], lms[rows, other])
        lo = torch.where(use_obstacle, torch.full((n,), ro + rl + _SPAWN_GAP, dtype=torch.float64),
                         torch.full((n,), 2 * rl + _SPAWN_GAP, dtype=torch.float64))
        hi = torch.where(use_obstacle, torch.full((n,), OBSTACLE_NEAR, dtype=torch.float64),
                         torch.full((n,), LANDMARK_NEAR, dtype=torch.float64))
        radius = lo + (hi - lo) * torch.rand(n, generator=generator, dtype=torch.float64)
        angle = 2 * math.pi * torch.rand(n, generator=generator, dtype=torch.float64)
        cand = anchor + radius.unsqueeze(-1) * torch.stack([angle.cos(), angle.sin()], -1)
        ok = (cand.abs() <= half).all(-1)
        if K:
            ok &= ((obst - cand.unsqueeze(1)).norm(dim=-1) >= ro + rl + _SPAWN_GAP).all(-1)
        d_lm = (lms - cand.unsqueeze(1)).norm(dim=-1)
        d_lm[rows, j] = math.inf
        ok &= (d_lm >= 2 * rl + _SPAWN_GAP).all(-1)
        take = ok & ~placed
        lms[rows[take], j[take]] = cand[take]
        placed |= ok
        if bool(placed.all()):
            break
    ids = chosen[placed]
    if len(ids):
        world.reset(options={"obstacle_pos": world.obstacle_pos[ids], "agent_pos": world.agent_pos[ids],
                             "landmark_pos": lms[placed], "agent_vel": world.agent_vel[ids],
                             "keep": world._keep[ids]}, env_ids=ids)
    return ids
