"""ORCA — optimal reciprocal collision avoidance, vectorized over every agent of every episode.

ORCA (van den Berg et al., "Reciprocal n-body collision avoidance", 2011; the paper's
ORCA baseline, section "Baselines") lets each agent pick the velocity closest to its
preferred one among those that avoid every neighbour for ``time_horizon`` seconds,
assuming the neighbour takes half of the avoidance effort:

1. **Half-planes** (:func:`orca_halfplanes`) — for each neighbour, the velocity obstacle
   is a cone truncated by a disc of radius ``r_a + r_b`` scaled by ``1 / time_horizon``.
   ``w = v_rel - p_rel / τ`` decides whether the relative velocity is closest to the
   cut-off disc or to one of the two legs; ``u`` is the smallest change that leaves the
   obstacle, and the permitted half-plane passes through ``v + λ u`` with normal ``u``
   (``λ = ½`` for agents, reciprocal; ``λ = 1`` for static obstacles, full
   responsibility). Bodies already overlapping use the cut-off disc of one time step.
2. **Linear programs** (:func:`solve_orca`) — RVO2's incremental 2-D programs:
   ``linearProgram2`` adds the half-planes one at a time and, when the current optimum
   violates one, re-optimizes on that line (``linearProgram1``, a 1-D interval problem);
   if the constraints are infeasible, ``linearProgram3`` minimizes the largest violation of
   the agent half-planes while keeping the obstacle ones hard, by solving a 2-D program on
   the bisectors of line pairs.

Lines are ``(point, direction)``; the permitted side is on the left of ``direction``. The
speed bound is the disc ``|v| <= max_speed``. Static obstacles are the world's immovable
circles, ordered first in each agent's constraint list (they are RVO2's "obstacle lines").

Why hand-written: no RVO2 binding installs from PyPI here, and a per-agent C++ loop would
not batch over episodes anyway. This port keeps RVO2's construction and its three
programs but runs each program step for all agents at once with numpy: loops go over
constraint slots (≤ ``max_neighbors + max_obstacles``), never over agents.
"""
from __future__ import annotations

import numpy as np

__all__ = ["orca_halfplanes", "solve_orca", "orca_velocities"]

EPS = 1e-5  # RVO2's RVO_EPSILON: lines this close to parallel are treated as parallel


def _det(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a, b):
    return (a * b).sum(-1)


def orca_halfplanes(rel_pos, rel_vel, vel, combined_radius, responsibility, time_horizon, time_step):
    """RVO2's ORCA half-plane for each (agent, neighbour) pair.

    ``rel_pos = p_other - p_self``, ``rel_vel = v_self - v_other`` and ``vel = v_self``:
    (..., 2); ``combined_radius``, ``responsibility``: broadcastable to (...). Returns
    ``(point, direction)``, each (..., 2): velocities ``v`` with
    ``det(direction, point - v) <= 0`` avoid the neighbour for ``time_horizon`` seconds.
    """
    rel_pos, rel_vel, vel = (np.asarray(x, dtype=np.float64) for x in (rel_pos, rel_vel, vel))
    r = np.broadcast_to(np.asarray(combined_radius, dtype=np.float64), rel_pos.shape[:-1])
    dist_sq = _dot(rel_pos, rel_pos)
    r_sq = r**2
    inv_tau = 1.0 / time_horizon
    collide = dist_sq <= r_sq
    # not colliding: vector from the cut-off centre to the relative velocity
    w = rel_vel - inv_tau * rel_pos
    w_len_sq = _dot(w, w)
    dot1 = _dot(w, rel_pos)
    on_disc = (dot1 < 0.0) & (dot1**2 > r_sq * w_len_sq)
    w_len = np.sqrt(np.maximum(w_len_sq, 1e-18))
    unit_w = w / w_len[..., None]
    disc_dir = np.stack([unit_w[..., 1], -unit_w[..., 0]], -1)
    disc_u = (r * inv_tau - w_len)[..., None] * unit_w
    # legs of the cone: left when the relative velocity is left of the centre line
    leg = np.sqrt(np.maximum(dist_sq - r_sq, 0.0))
    x, y = rel_pos[..., 0], rel_pos[..., 1]
    safe_dsq = np.maximum(dist_sq, 1e-18)
    left = np.stack([x * leg - y * r, x * r + y * leg], -1) / safe_dsq[..., None]
    right = -np.stack([x * leg + y * r, -x * r + y * leg], -1) / safe_dsq[..., None]
    leg_dir = np.where((_det(rel_pos, w) > 0.0)[..., None], left, right)
    leg_u = _dot(rel_vel, leg_dir)[..., None] * leg_dir - rel_vel
    # already colliding: cut-off disc of one time step
    inv_dt = 1.0 / time_step
    wc = rel_vel - inv_dt * rel_pos
    wc_len = np.sqrt(np.maximum(_dot(wc, wc), 1e-18))
    unit_wc = wc / wc_len[..., None]
    col_dir = np.stack([unit_wc[..., 1], -unit_wc[..., 0]], -1)
    col_u = (r * inv_dt - wc_len)[..., None] * unit_wc

    direction = np.where(collide[..., None], col_dir, np.where(on_disc[..., None], disc_dir, leg_dir))
    u = np.where(collide[..., None], col_u, np.where(on_disc[..., None], disc_u, leg_u))
    point = vel + np.asarray(responsibility, dtype=np.float64)[..., None] * u
    return point, direction


def _lp1(P, D, valid, i, radius, opt, direction_opt):
    """RVO2 ``linearProgram1``: optimum on line ``i`` subject to lines ``< i``; (ok, result)."""
    p, d = P[:, i], D[:, i]
    dot = _dot(p, d)
    disc = dot**2 + radius**2 - _dot(p, p)
    ok = disc >= 0.0                                     # the speed disc leaves part of line i
    sq = np.sqrt(np.maximum(disc, 0.0))
    t_left, t_right = -dot - sq, -dot + sq
    if i > 0:
        Pj, Dj, vj = P[:, :i], D[:, :i], valid[:, :i]
        denom = _det(d[:, None], Dj)
        numer = _det(Dj, p[:, None] - Pj)
        par = np.abs(denom) <= EPS
        ok &= ~(vj & par & (numer < 0.0)).any(1)        # parallel and on the wrong side
        t = numer / np.where(par, 1.0, denom)
        t_right = np.minimum(t_right, np.where(vj & ~par & (denom >= 0.0), t, np.inf).min(1))
        t_left = np.maximum(t_left, np.where(vj & ~par & (denom < 0.0), t, -np.inf).max(1))
        ok &= t_left <= t_right
    if direction_opt:
        t = np.where(_dot(opt, d) > 0.0, t_right, t_left)
    else:
        t = np.clip(_dot(d, opt - p), t_left, t_right)
    return ok, p + t[:, None] * d


def _lp2(P, D, valid, radius, opt, direction_opt):
    """RVO2 ``linearProgram2``: returns (index of the first infeasible line or M, result)."""
    A, M = valid.shape
    if direction_opt:
        res = opt * radius[:, None]
    else:
        n = np.linalg.norm(opt, axis=-1)
        res = np.where((n > radius)[:, None], opt / np.maximum(n, 1e-18)[:, None] * radius[:, None], opt)
    res = res.copy()
    fail = np.full(A, M)
    for i in range(M):
        viol = valid[:, i] & (fail == M) & (_det(D[:, i], P[:, i] - res) > 0.0)
        if not viol.any():
            continue
        r = np.flatnonzero(viol)
        ok, new = _lp1(P[r], D[r], valid[r], i, radius[r], opt[r], direction_opt)
        res[r[ok]] = new[ok]                 # on failure RVO2 keeps the previous result
        fail[r[~ok]] = i
    return fail, res


def _lp3(P, D, valid, n_obst, begin, radius, res):
    """RVO2 ``linearProgram3``: least-violation velocity when the program is infeasible."""
    A, M = valid.shape
    res = res.copy()
    distance = np.zeros(A)
    for i in range(M):
        need = valid[:, i] & (i >= begin) & (_det(D[:, i], P[:, i] - res) > distance)
        if not need.any():
            continue
        r = np.flatnonzero(need)
        Pi, Di = P[r, i], D[r, i]
        slots = max(i, n_obst)
        proj_P, proj_D = P[r, :slots].copy(), D[r, :slots].copy()
        proj_v = valid[r, :slots].copy()
        if i > n_obst:                       # bisectors between line i and agent lines j < i
            Pj, Dj = P[r, n_obst:i], D[r, n_obst:i]
            detm = _det(Di[:, None], Dj)
            par = np.abs(detm) <= EPS
            same = par & (_dot(Di[:, None], Dj) > 0.0)
            cross = Pi[:, None] + (_det(Dj, Pi[:, None] - Pj) / np.where(par, 1.0, detm))[..., None] * Di[:, None]
            proj_P[:, n_obst:i] = np.where(par[..., None], 0.5 * (Pi[:, None] + Pj), cross)
            bis = Dj - Di[:, None]
            proj_D[:, n_obst:i] = bis / np.maximum(np.linalg.norm(bis, axis=-1, keepdims=True), 1e-18)
            proj_v[:, n_obst:i] &= ~same
        opt = np.stack([-Di[:, 1], Di[:, 0]], -1)
        fail, new = _lp2(proj_P, proj_D, proj_v, radius[r], opt, True)
        res[r] = np.where((fail < slots)[:, None], res[r], new)
        distance[r] = _det(Di, Pi - res[r])
    return res


def solve_orca(points, directions, valid, pref_vel, max_speed, n_obstacle_lines=0):
    """New velocities from ORCA lines: RVO2's ``linearProgram2`` then ``linearProgram3``.

    ``points``, ``directions``: (A, M, 2) lines, the first ``n_obstacle_lines`` slots being
    obstacle lines (kept hard by the infeasible fallback); ``valid`` (A, M) bool marks the
    slots in use; ``pref_vel`` (A, 2); ``max_speed`` scalar or (A,). Returns (A, 2).
    """
    P, D = np.asarray(points, np.float64), np.asarray(directions, np.float64)
    valid = np.asarray(valid, bool)
    pref = np.asarray(pref_vel, np.float64)
    A, M = valid.shape
    if P.shape != (A, M, 2) or D.shape != (A, M, 2) or pref.shape != (A, 2):
        raise ValueError(f"solve_orca: expected points/directions (A, M, 2) and pref_vel (A, 2) with "
                         f"(A, M) = {(A, M)}, got {P.shape}, {D.shape}, {pref.shape}")
    radius = np.broadcast_to(np.asarray(max_speed, np.float64), (A,)).copy()
    fail, res = _lp2(P, D, valid, radius, pref, False)
    bad = np.flatnonzero(fail < M)
    if len(bad):
        res[bad] = _lp3(P[bad], D[bad], valid[bad], n_obstacle_lines, fail[bad], radius[bad], res[bad])
    return res


def _nearest(dist, k):
    """Indices of the ``k`` smallest entries along the last axis (unordered) and their values."""
    k = min(k, dist.shape[-1])
    if k == 0:
        return np.zeros(dist.shape[:-1] + (0,), np.int64), np.zeros(dist.shape[:-1] + (0,))
    idx = np.argpartition(dist, k - 1, axis=-1)[..., :k] if k < dist.shape[-1] else \
        np.broadcast_to(np.arange(k), dist.shape).copy()
    return idx, np.take_along_axis(dist, idx, -1)


def orca_velocities(pos, vel, pref_vel, obstacle_pos, *, agent_radius, obstacle_radius, alive=None,
                    max_speed=2.0, time_horizon=0.5, time_horizon_obst=0.3, neighbor_dist=3.0,
                    max_neighbors=8, max_obstacles=4, safety_margin=0.04, time_step=0.1):
    """ORCA velocities for batched episodes.

    ``pos``, ``vel``, ``pref_vel``: (B, N, 2); ``obstacle_pos`` (B, K, 2) static circles;
    ``alive`` (B, N) bool (dropped agents are neither neighbours nor moved). Each agent
    considers its ``max_neighbors`` nearest agents and ``max_obstacles`` nearest obstacles
    within ``neighbor_dist``; radii are inflated by ``safety_margin`` because the discrete
    actions only approximate the chosen velocity. Returns (B, N, 2).
    """
    pos, vel, pref = (np.asarray(x, np.float64) for x in (pos, vel, pref_vel))
    obst = np.asarray(obstacle_pos, np.float64)
    B, N, _ = pos.shape
    alive = np.ones((B, N), bool) if alive is None else np.asarray(alive, bool)
    # agent neighbours
    d_aa = np.linalg.norm(pos[:, None] - pos[:, :, None], axis=-1)          # (B, N, N)
    d_aa[:, np.arange(N), np.arange(N)] = np.inf
    d_aa = np.where(alive[:, None, :], d_aa, np.inf)
    ia, da = _nearest(d_aa, max_neighbors)
    b = np.arange(B)[:, None, None]
    rp_a = pos[b, ia] - pos[:, :, None]
    rv_a = vel[:, :, None] - vel[b, ia]
    pa, da_dir = orca_halfplanes(rp_a, rv_a, vel[:, :, None], 2 * (agent_radius + safety_margin), 0.5,
                                 time_horizon, time_step)
    va = da < neighbor_dist
    # obstacle neighbours: immovable circles, full responsibility
    d_ao = np.linalg.norm(obst[:, None] - pos[:, :, None], axis=-1)         # (B, N, K)
    io, do = _nearest(d_ao, max_obstacles)
    rp_o = obst[b, io] - pos[:, :, None]
    po, do_dir = orca_halfplanes(rp_o, np.broadcast_to(vel[:, :, None], rp_o.shape), vel[:, :, None],
                                 agent_radius + obstacle_radius + safety_margin, 1.0, time_horizon_obst,
                                 time_step)
    vo = do < neighbor_dist
    P = np.concatenate([po, pa], 2).reshape(B * N, -1, 2)
    D = np.concatenate([do_dir, da_dir], 2).reshape(B * N, -1, 2)
    V = (np.concatenate([vo, va], 2) & alive[..., None]).reshape(B * N, -1)
    out = solve_orca(P, D, V, pref.reshape(B * N, 2), max_speed, n_obstacle_lines=po.shape[2])
    return np.where(alive[..., None], out.reshape(B, N, 2), 0.0)
