"""From a planner's desired velocity to MPE's discrete actions — the one shared controller.

Every planning baseline (ORCA, RRT*, Voronoi) ends in a desired velocity per agent; the
particle world only takes one of five action ids (0 no-op, 1 −x, 2 +x, 3 −y, 4 +y).
:func:`velocity_to_action` picks the action whose *next* velocity tracks the desired one
best. The next velocity is exact, because MPE's update is linear in the action:

``v' = (1 - damping) * v + sensitivity * dt / mass * e(a)``

(``damping = 0.25``, ``sensitivity = 5``, ``dt = 0.1``: ``v' = 0.75 v + 0.5 e(a)``, so
speeds saturate at 2 m/s). The controller is greedy over one step, which is all a
velocity-level planner asks for.

Two helpers produce desired velocities that this controller tracks well:

* :func:`arrive_velocity` — head for a point at up to ``max_speed`` and slow down
  proportionally (``v = gain * offset``) near it, so agents stop *on* their landmark
  (for fixed teams success is judged at the end of the episode);
* :func:`track_path` — the path-tracking controller of the path planners (RRT*, Voronoi):
  follow a polyline of waypoints, switching to the next waypoint once close, and arrive
  at the last one.

Nothing here is specific to a planner, so that a difference in results between planners
comes from planning, not from control. Works on numpy arrays and torch tensors alike.
"""
from __future__ import annotations

import numpy as np
import torch

from ..envs.particle import ACTION_DIRECTIONS, PHYSICS

__all__ = ["velocity_to_action", "next_velocities", "arrive_velocity", "track_path", "pad_paths",
           "MAX_SPEED", "ARRIVE_GAIN", "GLOBAL_STEP"]

#: Environment steps per global step (goal re-assignment and path re-planning period).
GLOBAL_STEP = 3

#: Terminal speed of MPE agents under a constant action (m/s): v = 0.75 v + 0.5.
MAX_SPEED = PHYSICS["sensitivity"] * PHYSICS["dt"] / PHYSICS["mass"] / PHYSICS["damping"]
#: Default proportional gain of :func:`arrive_velocity` (1/s); tuned so agents stop on target.
ARRIVE_GAIN = 3.0

_KICK = np.asarray(ACTION_DIRECTIONS) * PHYSICS["sensitivity"] * PHYSICS["dt"] / PHYSICS["mass"]


def next_velocities(vel: np.ndarray) -> np.ndarray:
    """Velocity after one step under each of the 5 actions, ignoring contacts: (..., 5, 2)."""
    vel = np.asarray(vel, dtype=np.float64)
    return vel[..., None, :] * (1.0 - PHYSICS["damping"]) + _KICK


def velocity_to_action(vel, desired_vel):
    """Action id (0–4) whose next velocity is closest to ``desired_vel``.

    ``vel``, ``desired_vel``: (..., 2) current and wanted velocities (numpy or torch).
    Returns (...) int64 of the same kind (a torch tensor on ``vel``'s device for torch).

    >>> int(velocity_to_action(np.zeros(2), np.array([0.5, 0.0])))  # push +x
    2
    """
    is_torch = torch.is_tensor(vel) or torch.is_tensor(desired_vel)
    device = vel.device if torch.is_tensor(vel) else (desired_vel.device if is_torch else None)
    v = _as_numpy(vel, "vel")
    d = _as_numpy(desired_vel, "desired_vel")
    if v.shape != d.shape:
        raise ValueError(f"velocity_to_action: expected vel and desired_vel of the same shape (..., 2), "
                         f"got {v.shape} and {d.shape}")
    err = ((next_velocities(v) - d[..., None, :]) ** 2).sum(-1)      # (..., 5)
    act = err.argmin(-1).astype(np.int64)
    return torch.from_numpy(act).to(device) if is_torch else act


def arrive_velocity(pos, target, max_speed: float = MAX_SPEED, gain: float = ARRIVE_GAIN) -> np.ndarray:
    """Desired velocity toward ``target``: ``gain * (target - pos)`` capped at ``max_speed``.

    (..., 2) numpy in, (..., 2) numpy out. Far away it is full speed; within
    ``max_speed / gain`` metres it shrinks linearly, so the agent brakes onto the target.
    """
    off = _as_numpy(target, "target") - _as_numpy(pos, "pos")
    v = gain * off
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    return v * np.minimum(1.0, max_speed / np.maximum(speed, 1e-12))


def track_path(pos, waypoints, index, switch_dist: float = 0.25, max_speed: float = MAX_SPEED,
               gain: float = ARRIVE_GAIN):
    """Path-tracking controller: desired velocity along polylines, and the advanced index.

    ``pos`` (A, 2); ``waypoints`` (A, P, 2), each row a path whose last point is the goal
    (shorter paths padded by repeating their goal); ``index`` (A,) int, the waypoint each
    agent is heading for. An agent moves on to the next waypoint once within
    ``switch_dist`` of the current one; between waypoints it flies at ``max_speed``, and it
    arrives (brakes) on the last one. Returns ``(desired_vel (A, 2), new_index (A,))``.
    """
    pos = _as_numpy(pos, "pos")
    wp = _as_numpy(waypoints, "waypoints")
    idx = np.asarray(index, dtype=np.int64).copy()
    if wp.ndim != 3 or wp.shape[0] != pos.shape[0] or wp.shape[1] < 1:
        raise ValueError(f"track_path: expected waypoints of shape (A, P>=1, 2) with A={pos.shape[0]}, "
                         f"got {wp.shape}")
    last = wp.shape[1] - 1
    rows = np.arange(len(pos))
    for _ in range(wp.shape[1]):  # skip every waypoint already within reach
        target = wp[rows, np.minimum(idx, last)]
        close = (np.linalg.norm(target - pos, axis=-1) < switch_dist) & (idx < last)
        if not close.any():
            break
        idx = np.where(close, idx + 1, idx)
    idx = np.minimum(idx, last)
    target = wp[rows, idx]
    final = (idx == last) | (np.abs(wp[rows, idx] - wp[:, -1]).sum(-1) == 0.0)
    off = target - pos
    dist = np.linalg.norm(off, axis=-1, keepdims=True)
    cruise = off / np.maximum(dist, 1e-12) * max_speed
    desired = np.where(final[:, None], arrive_velocity(pos, target, max_speed, gain), cruise)
    return desired, idx


def _as_numpy(x, name):
    if torch.is_tensor(x):
        x = x.detach().cpu().numpy()
    x = np.asarray(x, dtype=np.float64)
    if x.ndim < 1 or x.shape[-1] != 2:
        raise ValueError(f"{name}: expected an array of 2-D vectors with shape (..., 2), got {x.shape}")
    return x


def pad_paths(paths, P):
    """Pad waypoint rows (B, N, p, 2) to length P by repeating each row's last point."""
    if paths.shape[2] == P:
        return paths
    tail = np.repeat(paths[:, :, -1:], P - paths.shape[2], axis=2)
    return np.concatenate([paths, tail], 2)
