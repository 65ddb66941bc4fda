"""What MASP's networks see: features of a world's observation, in D = 2 (particles) or 3 (drones) dimensions.

* Goal Matcher: :func:`gm_inputs` (agent and goal nodes, the pair distances of eq. 4);
* executor: :func:`pair_features` (each other agent), :func:`assigned_goal_features` (the
  goal) and the particle world's :func:`obstacle_features` (the drones' own input is their
  flight state, :func:`masp_lite.nets.drones.drone_state_features`);
* critics: :func:`global_features` (landmarks covered and reached, time left).

One definition serves both worlds, each passing its sensing radius and speed scale (the
networks' class attributes, :class:`~masp_lite.nets.masp.MASPNets`). They live with the networks,
not the worlds: the scales and clips are modelling choices (documented here), and the worlds and
planners keep the raw observation. Particle inputs are in metres (MPE's dynamics do not scale with
the map), relative vectors clipped at ``SENSE`` = 1 m (collisions happen below 0.2 m); the Goal
Matcher's positions are divided by the map's half-width.
"""
from __future__ import annotations

import torch

__all__ = ["pair_features", "goal_features", "assigned_goal_features", "obstacle_features", "global_features",
           "gm_inputs", "MAX_SPEED", "SENSE"]

MAX_SPEED = 2.0
"""MPE's terminal speed under a constant action (m/s); velocities are divided by it."""
SENSE = 1.0
"""Metres at which neighbour and obstacle vectors are clipped."""


def _clip(rel: torch.Tensor, radius: float) -> tuple[torch.Tensor, torch.Tensor]:
    d = rel.norm(dim=-1, keepdim=True)
    return rel * (radius / d.clamp(min=radius)), d


def pair_features(pos: torch.Tensor, vel: torch.Tensor, sense: float = SENSE, max_speed: float = MAX_SPEED
                  ) -> torch.Tensor:
    """(B, N, N, 2D + 2): agent ``j`` seen from agent ``k`` at ``[b, k, j]``, in D = 2 or 3 dimensions.

    ``[rel / sense (D, clipped to norm 1), min(dist, sense) / sense, (v_j - v_k) / max_speed (D),
    is_self]``; the drones pass their own ``sense`` and ``max_speed`` (:mod:`masp_lite.nets.drones`).
    """
    rel, d = _clip(pos.unsqueeze(1) - pos.unsqueeze(2), sense)
    dv = (vel.unsqueeze(1) - vel.unsqueeze(2)) / max_speed
    N = pos.shape[1]
    eye = torch.eye(N, dtype=pos.dtype, device=pos.device).expand(*pos.shape[:1], N, N).unsqueeze(-1)
    return torch.cat([rel / sense, d.clamp(max=sense) / sense, dv, eye], dim=-1)


def goal_features(pos: torch.Tensor, vel: torch.Tensor, goal_pos: torch.Tensor, max_speed: float = MAX_SPEED
                  ) -> torch.Tensor:
    """(B, N, 2D + 2): each agent's assigned goal ``goal_pos`` (B, N, D) seen from the agent.

    ``[unit direction (D), min(dist, 1 m), log(1 + dist), own velocity / max_speed (D)]``.
    """
    rel = goal_pos - pos
    d = rel.norm(dim=-1, keepdim=True)
    unit = rel / d.clamp(min=1e-6)
    return torch.cat([unit, d.clamp(max=1.0), torch.log1p(d), vel / max_speed], dim=-1)


def assigned_goal_features(obs: dict, goals: torch.Tensor, max_speed: float = MAX_SPEED) -> torch.Tensor:
    """:func:`goal_features` of the landmark each agent is assigned (goal indices ``goals`` (B, N))."""
    pos = obs["agent_pos"]
    goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(pos))
    return goal_features(pos, obs["agent_vel"], goal_pos, max_speed)


def obstacle_features(pos: torch.Tensor, obstacle_pos: torch.Tensor, count: int) -> torch.Tensor:
    """(B, N, 3 * count): the ``count`` nearest obstacles, nearest first.

    Each is ``[rel / SENSE (clipped to norm 1), min(dist, SENSE) / SENSE]``; missing ones
    (fewer than ``count`` obstacles) read ``[0, 0, 1]``, an obstacle at the sensing edge.
    """
    B, N = pos.shape[:2]
    K = obstacle_pos.shape[1]
    pad = torch.tensor([0.0, 0.0, 1.0], dtype=pos.dtype, device=pos.device)
    if K == 0:
        return pad.repeat(B, N, count)
    rel = obstacle_pos.unsqueeze(1) - pos.unsqueeze(2)                  # (B, N, K, 2)
    d = rel.norm(dim=-1)
    k = min(count, K)
    d_near, idx = d.topk(k, dim=-1, largest=False)
    rel_near = torch.gather(rel, 2, idx.unsqueeze(-1).expand(B, N, k, 2))
    rel_c, _ = _clip(rel_near, SENSE)
    feats = torch.cat([rel_c / SENSE, d_near.clamp(max=SENSE).unsqueeze(-1) / SENSE], dim=-1)
    if k < count:
        feats = torch.cat([feats, pad.expand(B, N, count - k, 3)], dim=2)
    return feats.reshape(B, N, 3 * count)


def global_features(obs: dict, horizon: int) -> torch.Tensor:
    """(B, N, 3) centralized inputs for the critics: landmarks covered now, ever reached, time left."""
    cov = obs["covered"].to(obs["agent_pos"].dtype).mean(-1, keepdim=True)
    rea = obs["reached"].to(cov.dtype).mean(-1, keepdim=True)
    left = 1.0 - obs["t"].to(cov.dtype).unsqueeze(-1) / horizon
    return torch.cat([cov, rea, left], dim=-1).unsqueeze(1).expand(-1, obs["alive"].shape[1], -1)


def gm_inputs(obs: dict, scale: float, max_speed: float = MAX_SPEED):
    """Goal Matcher inputs: agent nodes (B, N, 2D + 1), goal nodes (B, M, D + 2), pair distances (B, N, M, 2).

    Pair ``(k, j)``: ``[D_kj, D_kj - min_i D_ij]`` — the L2 distance of eq. 4 and how much
    farther agent ``k`` is from goal ``j`` than the closest alive agent (0 when ``k`` is
    the closest).

    Agent node: ``[pos / scale (D), vel / max_speed (D), distance to its nearest goal / scale]``;
    goal node: ``[pos / scale (D), covered, distance to its nearest alive agent / scale]``
    (``scale = world_size / 2``). The two nearest-distances are position information the
    paper's nodes carry implicitly; giving them explicitly lets agent ``k`` compare its own
    distance ``D_kj`` with the closest competitor's, which speeds up learning to avoid
    picking the same goal as another agent.
    """
    dist = torch.cdist(obs["agent_pos"], obs["landmark_pos"]) / scale
    alive = obs["alive"]
    near_goal = dist.min(-1).values.unsqueeze(-1)
    big = torch.finfo(dist.dtype).max
    near_agent = dist.masked_fill(~alive.unsqueeze(-1), big).min(1).values.clamp(max=4.0).unsqueeze(-1)
    a = torch.cat([obs["agent_pos"] / scale, obs["agent_vel"] / max_speed, near_goal], dim=-1)
    g = torch.cat([obs["landmark_pos"] / scale, obs["covered"].to(a.dtype).unsqueeze(-1), near_agent], dim=-1)
    margin = (dist - near_agent.transpose(1, 2)).clamp(min=0.0, max=4.0)
    return a, g, torch.stack([dist, margin], dim=-1)
