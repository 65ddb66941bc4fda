"""RRT* — asymptotically optimal sampling-based paths, one tree per agent, all grown at once.

RRT* (Karaman & Frazzoli 2011; the paper's RRT* baseline, section "Baselines") grows a
tree from the start by sampling points; each new point is connected to the *cheapest*
collision-free parent among its near neighbours (choose-parent) and then offered as a
cheaper parent to those neighbours (**rewiring**), which is what makes paths improve
towards the optimum as samples grow. Here, per agent, for a given start and goal:

1. if the straight segment to the goal is free, it is the optimal path and no tree is
   grown (a goal-biased RRT* would find it at its first goal sample);
2. otherwise ``samples`` iterations of RRT*: sample (the goal with probability
   ``goal_bias``, else uniformly in the start–goal box grown by ``box_pad``), steer from the
   nearest node by at most ``step_size``, choose the cheapest parent among the
   ``k_near`` nearest nodes within ``rewire_radius``, rewire them (:func:`rewire`), and
   push cost decreases down to descendants;
3. the goal joins the tree through its cheapest free node; the node path is then
   **shortcut** greedily (from each waypoint jump to the furthest one in line of sight).

Obstacles are circles (the world's obstacles and the other agents at planning time,
already inflated by the caller by a safety margin). A circle whose margin holds the start
or goal counts with its bare radius, and one the agent already touches, or that covers
its goal, is ignored (:func:`agent_circles`; a neighbour on the landmark moves on its
own). Each tree considers only its ``max_circles`` circles nearest to the start–goal
segment.

Why hand-written: no maintained Python RRT* batches many small trees; the loops below run
over iterations, and every iteration updates all agents' trees with numpy at once, so 50
agents plan in a few milliseconds (scipy's KD-tree would need one tree per agent per
iteration, slower at these sizes than brute-force distances).
"""
from __future__ import annotations

import numpy as np

__all__ = ["segment_hits", "agent_circles", "segments_blocked", "rewire", "rrt_star", "shortcut", "plan_rrt_star",
           "path_length"]


def segment_hits(p0, p1, centres, radii):
    """Whether the segment ``p0 → p1`` comes closer than ``radii`` to each circle centre.

    ``p0``, ``p1``: (..., 2); ``centres``: (..., C, 2); ``radii``: broadcastable to (..., C).
    Returns (..., C) bool.
    """
    d = p1 - p0
    len_sq = np.maximum((d * d).sum(-1), 1e-18)[..., None]
    t = np.clip(((centres - p0[..., None, :]) * d[..., None, :]).sum(-1) / len_sq, 0.0, 1.0)
    closest = p0[..., None, :] + t[..., None] * d[..., None, :]
    return ((closest - centres) ** 2).sum(-1) < np.asarray(radii) ** 2


def agent_circles(start, goal, centres, radii, mask, self_index=None, margin=0.05):
    """Per-agent circles to avoid: radii (B, N, C) and mask (B, N, C).

    ``radii`` (C,) are inflated by ``margin``. A circle whose inflated disc holds the agent's
    start or goal shrinks to just inside that point, but never below its bare radius
    (``radii - margin``): the agent may leave or approach it, not run into it. One whose
    bare disc holds them is dropped (already in contact, or a goal under a neighbour). The
    agent's own circle (``self_index``) is dropped.
    """
    def dist_sq(p):
        return ((centres[:, None] - p[:, :, None]) ** 2).sum(-1)

    near = np.minimum(dist_sq(start), dist_sq(goal))
    # near a circle: shrink it to just inside the agent's distance (never below the bare radius)
    r = np.clip(np.sqrt(near) - 0.005, radii - margin, radii)
    m = np.broadcast_to(mask[:, None, :], r.shape).copy() & (near >= (radii - margin) ** 2)
    if self_index is not None:
        np.put_along_axis(m, np.asarray(self_index)[..., None], False, -1)
    return r, m


def segments_blocked(start, end, centres, radii, mask, self_index=None, goal=None, margin=0.05):
    """(B, N) bool: the segment ``start → end`` of each agent hits a circle it must avoid."""
    r, m = agent_circles(start, end if goal is None else goal, centres, radii, mask, self_index, margin)
    return (segment_hits(start, end, centres[:, None], r) & m).any(-1)


def path_length(points):
    """Length of polylines (..., P, 2) → (...)."""
    return np.linalg.norm(np.diff(points, axis=-2), axis=-1).sum(-1)


def rewire(nodes, cost, parent, new, near, free):
    """The RRT* rewire step for one new node, vectorized over trees.

    ``nodes`` (A, T, 2), ``cost`` (A, T), ``parent`` (A, T) long; ``new`` (A,) index of the
    node just added; ``near`` (A, k) indices of its near nodes; ``free`` (A, k) bool, the
    edge new–near is collision-free. A near node whose cost drops by going through the new
    node gets the new node as parent. Updates ``cost``/``parent`` in place; returns the
    (A, k) mask of rewired nodes.
    """
    rows = np.arange(len(nodes))[:, None]
    through = cost[rows[:, 0], new][:, None] + np.linalg.norm(nodes[rows, near] - nodes[rows[:, 0], new][:, None],
                                                              axis=-1)
    better = free & (through < cost[rows, near] - 1e-12) & (near != new[:, None])
    r, c = np.nonzero(better)
    parent[r, near[r, c]] = new[r]
    cost[r, near[r, c]] = through[r, c]
    return better


def _propagate(nodes, cost, parent, valid):
    """Push cost decreases from rewired nodes down their subtrees (a few vectorized sweeps)."""
    rows = np.arange(len(nodes))[:, None]
    edge = np.linalg.norm(nodes - nodes[rows, parent], axis=-1)
    for _ in range(nodes.shape[1]):
        new = np.where(valid & (parent >= 0), cost[rows, np.maximum(parent, 0)] + edge, cost)
        if np.allclose(new, cost):
            return
        cost[:] = new


def rrt_star(start, goal, centres, radii, cmask, rng, *, lo, hi, samples=60, step_size=1.0,
             rewire_radius=1.5, goal_bias=0.2, k_near=8):
    """Grow one RRT* tree per row and return node paths from start to goal: (A, P, 2).

    ``start``, ``goal`` (A, 2); ``centres`` (A, C, 2), ``radii`` (A, C), ``cmask`` (A, C)
    the circles to avoid; ``lo``, ``hi`` (A, 2) the sampling box. Rows are padded with
    their goal. When no node sees the goal, the path ends at the node nearest to it instead
    (the agent gets closer and plans again; it never cuts through an obstacle).
    """
    A, T = len(start), samples + 1
    nodes = np.zeros((A, T, 2))
    nodes[:, 0] = start
    cost = np.full((A, T), np.inf)
    cost[:, 0] = 0.0
    parent = np.full((A, T), -1)
    valid = np.zeros((A, T), bool)
    valid[:, 0] = True
    rows = np.arange(A)

    def free(p0, p1):  # (A, k, 2) pairs -> (A, k) collision-free
        return ~(segment_hits(p0, p1, centres[:, None], radii[:, None]) & cmask[:, None]).any(-1)

    for it in range(1, T):
        pick = rng.random(A) < goal_bias
        s = np.where(pick[:, None], goal, lo + rng.random((A, 2)) * (hi - lo))
        d = np.linalg.norm(nodes[:, :it] - s[:, None], axis=-1)
        d[~valid[:, :it]] = np.inf
        near0 = d.argmin(1)
        base = nodes[rows, near0]
        off = s - base
        dist = np.linalg.norm(off, axis=-1, keepdims=True)
        new_pt = base + off * np.minimum(1.0, step_size / np.maximum(dist, 1e-12))
        # near set: the k nearest tree nodes within the rewire radius (always incl. the nearest)
        dn = np.linalg.norm(nodes[:, :it] - new_pt[:, None], axis=-1)
        dn[~valid[:, :it]] = np.inf
        k = min(k_near, it)
        near = np.argpartition(dn, k - 1, axis=1)[:, :k] if k < it else np.tile(np.arange(it), (A, 1))
        dk = np.take_along_axis(dn, near, 1)
        ok_near = (dk <= rewire_radius) | (near == near0[:, None])
        ok_near &= np.isfinite(dk)
        edge_free = free(np.broadcast_to(new_pt[:, None], (A, k, 2)), nodes[rows[:, None], near]) & ok_near
        # choose-parent: the cheapest collision-free way to reach the new point
        via = np.where(edge_free, cost[rows[:, None], near] + dk, np.inf)
        best = via.argmin(1)
        added = np.isfinite(via[rows, best])
        nodes[added, it] = new_pt[added]
        cost[added, it] = via[rows, best][added]
        parent[added, it] = near[rows, best][added]
        valid[added, it] = True
        # rewire the near nodes through the new one
        newi = np.full(A, it)
        if rewire(nodes, cost, parent, newi, near, edge_free & added[:, None]).any():
            _propagate(nodes, cost, parent, valid)
    # join the goal through its cheapest visible node
    to_goal = np.linalg.norm(nodes - goal[:, None], axis=-1)
    sees = free(np.broadcast_to(goal[:, None], (A, T, 2)), nodes) & valid
    via = np.where(sees, cost + to_goal, np.inf)
    reached = np.isfinite(via.min(1))
    last = np.where(reached, via.argmin(1), np.where(valid, to_goal, np.inf).argmin(1))
    # walk parents back to the root; an unreached goal is replaced by the node nearest to it
    end = np.where(reached[:, None], goal, nodes[rows, last])
    path = np.repeat(end[:, None], T + 1, axis=1)
    chain = np.zeros((A, T), np.int64)
    cur, depth = last.copy(), np.zeros(A, np.int64)
    for _ in range(T):
        live = cur >= 0
        if not live.any():
            break
        chain[live, depth[live]] = cur[live]
        depth[live] += 1
        cur = np.where(live, parent[rows, np.maximum(cur, 0)], -1)
    for a in range(A):  # reverse each chain (short) into start-first order
        pts = nodes[a, chain[a, : depth[a]][::-1]]
        path[a, : len(pts)] = pts
    return path[:, : int(depth.max()) + 1]  # one goal column after the longest chain


def shortcut(path, centres, radii, cmask):
    """Greedy line-of-sight shortcutting of polylines (A, P, 2): keep the start, then jump to
    the furthest waypoint visible from the current one. Returns (A, P, 2), goal-padded."""
    A, P, _ = path.shape
    hits = segment_hits(path[:, :, None], path[:, None, :], centres[:, None, None], radii[:, None, None])
    sees = ~(hits & cmask[:, None, None]).any(-1)                       # (A, P, P)
    sees |= np.eye(P, dtype=bool)                                      # a point sees itself
    ahead = np.triu(np.ones((P, P), bool), 1)
    # next waypoint: furthest visible one ahead (or the next one when nothing is visible)
    far = np.where(sees & ahead, np.arange(P), -1).max(-1)
    jump = np.where(far > np.arange(P), far, np.minimum(np.arange(P) + 1, P - 1))
    out = np.repeat(path[:, -1:], P, axis=1)
    cur = np.zeros(A, np.int64)
    rows = np.arange(A)
    for k in range(P):
        out[:, k] = path[rows, cur]
        if (cur == P - 1).all():
            break
        cur = jump[rows, cur]
    return out[:, 1:]  # drop the start: waypoints to head for


def plan_rrt_star(start, goal, centres, radii, mask, replan, rng, *, self_index=None, bounds=None,
                  samples=60, step_size=1.0, rewire_radius=1.5, goal_bias=0.2, box_pad=2.0, max_circles=24,
                  margin=0.05, previous=None):
    """Waypoint paths (B, N, P, 2) for the agents in ``replan`` (B, N); others get their goal.

    ``start``, ``goal`` (B, N, 2); circles ``centres`` (B, C, 2) with ``radii`` (C,) (inflated
    by ``margin``, see :func:`agent_circles`) and
    ``mask`` (B, C); ``self_index`` (B, N) the circle of each agent itself; ``bounds`` the
    half side of the map (samples stay inside). ``previous`` (B, N, P', 2), the rest of
    the current paths from the current position: a replanned agent keeps it when it is
    still free and not longer than the new path (paths are reused between replans).
    """
    B, N, _ = start.shape
    out = [goal[:, :, None]]
    ra, m = agent_circles(start, goal, centres, radii, mask, self_index, margin)
    m &= replan[..., None]
    direct = ~(segment_hits(start, goal, centres[:, None], ra) & m).any(-1)
    hard = np.argwhere(replan & ~direct)                                # (A, 2) of (b, n)
    P = 1
    if len(hard):
        b, n = hard[:, 0], hard[:, 1]
        s, g = start[b, n], goal[b, n]
        # the circles nearest to the start–goal segment
        seg = g - s
        t = np.clip(((centres[b] - s[:, None]) * seg[:, None]).sum(-1) / np.maximum((seg**2).sum(-1), 1e-12)[:, None],
                    0, 1)
        gap = np.linalg.norm(s[:, None] + t[..., None] * seg[:, None] - centres[b], axis=-1) - ra[b, n]
        gap[~m[b, n]] = np.inf
        c = min(max_circles, gap.shape[1])
        pick = np.argsort(gap, axis=1)[:, :c]
        cen, rad = np.take_along_axis(centres[b], pick[..., None], 1), np.take_along_axis(ra[b, n], pick, 1)
        cm = np.isfinite(np.take_along_axis(gap, pick, 1))
        lo, hi = np.minimum(s, g) - box_pad, np.maximum(s, g) + box_pad
        if bounds is not None:
            lo, hi = np.maximum(lo, -bounds), np.minimum(hi, bounds)
        nodes = rrt_star(s, g, cen, rad, cm, rng, lo=lo, hi=hi, samples=samples, step_size=step_size,
                         rewire_radius=rewire_radius, goal_bias=goal_bias)
        paths = shortcut(nodes, cen, rad, cm)
        P = paths.shape[1]
        full = np.repeat(goal[:, :, None], P, axis=2)
        full[b, n] = paths
        out = [full]
    new = out[0]
    if previous is not None:
        prev_len = path_length(np.concatenate([start[:, :, None], previous], 2))
        new_len = path_length(np.concatenate([start[:, :, None], new], 2))
        seg_a = np.concatenate([start[:, :, None], previous[:, :, :-1]], 2)
        hit = segment_hits(seg_a, previous, centres[:, None, None], ra[:, :, None]) & m[:, :, None]
        complete = np.abs(new[:, :, -1] - goal).sum(-1) < 1e-9
        keep = replan & ~hit.any((-1, -2)) & ((prev_len <= new_len + 1e-9) | ~complete) & ~direct
        if keep.any():
            Pm = max(new.shape[2], previous.shape[2])
            pad = lambda x: np.concatenate([x, np.repeat(x[:, :, -1:], Pm - x.shape[2], 2)], 2)  # noqa: E731
            new = np.where(keep[..., None, None], pad(previous), pad(new))
    return new
