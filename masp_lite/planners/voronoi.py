"""Voronoi roadmap planning: shortest routes along the safe edges of a Voronoi diagram.

The paper's Voronoi baseline (section "Baselines"; Hu et al. 2020) partitions the map into
Voronoi cells and plans "from the starting point to the destination at a safe distance".
Every point of a Voronoi edge is equidistant from the two bodies whose cells it
separates, and as far from them as it can be — the edges form the map's maximum-clearance
roadmap. Per episode, every global step:

1. **Diagram** — ``scipy.spatial.Voronoi`` over the alive agents, the obstacles and a ring
   of points on the map's border (the walls; every cell inside the map is then bounded);
2. **Safe edges** (:func:`safe_edges`) — an edge is kept when it stays inside the map and
   its clearance (distance from the segment to its two generators) is at least
   ``agent_radius + generator radius + margin``;
3. **Graph search** — each agent's start joins the vertices of its own cell, each goal the
   vertices of the cell it lies in (the joining segments must be free too), and one
   ``scipy.sparse.csgraph.dijkstra`` call from all starts finds every shortest route
   (start nodes only leave, goal nodes only enter, so no route passes through another
   agent's start or goal);
4. **Path** — the route's vertices, shortened by line-of-sight shortcuts that keep the same
   clearance (:func:`masp_lite.planners.rrt_star.shortcut`); when the straight segment to
   the goal is free that is the result. An agent with no route heads straight for its goal.

Nothing here is hand-written beyond the graph construction: diagram, search and
shortcutting use scipy and the RRT* module's segment tests.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import Voronoi

from .rrt_star import agent_circles, segment_hits, shortcut

__all__ = ["safe_edges", "voronoi_paths", "plan_voronoi", "boundary_ring", "route"]


def boundary_ring(half_size: float, spacing: float = 0.5, offset: float = 0.0) -> np.ndarray:
    """Points every ``spacing`` metres on a square of half side ``half_size + offset``: (M, 2).

    On the map's border they stand for the walls: the Voronoi edges between an obstacle and
    the border run half-way between them, so gaps next to the walls are on the roadmap.
    """
    h = half_size + offset
    n = max(4, int(np.ceil(2 * h / spacing)))
    s = np.linspace(-h, h, n, endpoint=False)
    return np.concatenate([np.stack([s, np.full(n, -h)], 1), np.stack([np.full(n, h), s], 1),
                           np.stack([-s, np.full(n, h)], 1), np.stack([np.full(n, -h), -s], 1)])


def safe_edges(vor: Voronoi, gen_radius: np.ndarray, agent_radius: float, margin: float,
               half_size: float) -> np.ndarray:
    """Finite Voronoi edges (E, 2) of vertex ids that an agent can follow at a safe distance."""
    rv = np.asarray(vor.ridge_vertices)
    rp = np.asarray(vor.ridge_points)
    finite = (rv >= 0).all(1)
    rv, rp = rv[finite], rp[finite]
    v = vor.vertices
    inside = (np.abs(v) <= half_size - agent_radius).all(1)
    a, b = v[rv[:, 0]], v[rv[:, 1]]
    gen = vor.points[rp[:, 0]]                     # both generators are equally far from the edge
    clearance = np.sqrt(((_closest(a, b, gen) - gen) ** 2).sum(-1))
    need = agent_radius + np.maximum(gen_radius[rp[:, 0]], gen_radius[rp[:, 1]]) + margin
    keep = (clearance >= need) & inside[rv[:, 0]] & inside[rv[:, 1]]
    return rv[keep]


def _closest(a, b, p):
    d = b - a
    t = np.clip(((p - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-18), 0.0, 1.0)
    return a + t[..., None] * d


def voronoi_paths(start, goal, obstacles, *, agent_radius, obstacle_radius, half_size, margin=0.05):
    """Routes for one episode: ``start``, ``goal`` (n, 2) of the alive agents, ``obstacles``
    (K, 2). Returns a list of n waypoint arrays (p_i, 2) ending at the goal (start excluded)."""
    n, K = len(start), len(obstacles)
    ring = boundary_ring(half_size)
    pts = np.concatenate([start, obstacles, ring])
    gen_r = np.concatenate([np.full(n, agent_radius), np.full(K, obstacle_radius), np.zeros(len(ring))])
    vor = Voronoi(pts)
    V = len(vor.vertices)
    edges = safe_edges(vor, gen_r, agent_radius, margin, half_size)
    # circles to avoid when joining starts/goals to the roadmap: obstacles and other agents
    circ = np.concatenate([obstacles, start])
    circ_r = np.concatenate([np.full(K, obstacle_radius), np.full(n, agent_radius)]) + agent_radius + margin
    rows, cols = [edges[:, 0], edges[:, 1]], [edges[:, 1], edges[:, 0]]
    w = [np.linalg.norm(vor.vertices[edges[:, 0]] - vor.vertices[edges[:, 1]], axis=1)] * 2
    owner = np.argmin(((goal[:, None] - pts[None, : n + K]) ** 2).sum(-1), 1)    # cell holding each goal
    radius, avoid = _circles(start, goal, circ, circ_r, K, margin)
    for i in range(n):
        for node, other, cell, outgoing in ((V + i, start[i], i, True), (V + n + i, goal[i], owner[i], False)):
            region = [r for r in vor.regions[vor.point_region[cell]] if r >= 0]
            if not region:
                continue
            vs = np.asarray(region)
            ok = ~(segment_hits(np.broadcast_to(other, (len(vs), 2)), vor.vertices[vs], circ, radius[i])
                   & avoid[i]).any(-1)
            vs = vs[ok]
            d = np.linalg.norm(vor.vertices[vs] - other, axis=1)
            rows.append(np.full(len(vs), node) if outgoing else vs)
            cols.append(vs if outgoing else np.full(len(vs), node))
            w.append(d)
    size = V + 2 * n
    graph = csr_matrix((np.concatenate(w) + 1e-9, (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))
    _, pred = dijkstra(graph, directed=True, indices=V + np.arange(n), return_predecessors=True)
    paths = []
    for i in range(n):
        nodes = route(pred[i], V + i, V + n + i)
        if not nodes:                                      # no route: straight to the goal
            paths.append(goal[i][None])
            continue
        paths.append(np.asarray([vor.vertices[r] for r in nodes if r < V] + [goal[i]]))
    return paths


def route(predecessors, source: int, target: int) -> list[int]:
    """Node ids from ``source`` to ``target`` (both included) along a shortest-path tree.

    ``predecessors`` is one row of ``scipy.sparse.csgraph.dijkstra(...,
    return_predecessors=True)`` for ``source``: the node before each node on its shortest
    path, negative where there is none. Returns ``[]`` when ``target`` is unreachable.

    >>> route(np.array([-9999, 0, 1, -9999]), 0, 2)
    [0, 1, 2]
    """
    out, node = [], int(target)
    for _ in range(len(predecessors) + 1):
        out.append(node)
        if node == source:
            return out[::-1]
        node = int(predecessors[node])
        if node < 0:
            return []
    return []


def _circles(start, goal, circ, circ_r, K, margin):
    """Per-agent radii and masks (n, C) of the circles (obstacles, then agents) to avoid."""
    n = len(start)
    r, m = agent_circles(start[None], goal[None], circ[None], circ_r, np.ones((1, len(circ)), bool),
                         self_index=(K + np.arange(n))[None], margin=margin)
    return r[0], m[0]


def plan_voronoi(pos, goals, obstacles, alive, *, agent_radius, obstacle_radius, half_size, margin=0.05):
    """Shortcut Voronoi paths for batched episodes: (B, N, P, 2) goal-padded waypoints.

    ``pos``, ``goals`` (B, N, 2); ``obstacles`` (B, K, 2); ``alive`` (B, N). Dropped agents
    get their own position as path (and are not generators of the diagram).
    """
    B, N, _ = pos.shape
    K = obstacles.shape[1]
    per_env = []
    for b in range(B):
        idx = np.flatnonzero(alive[b])
        raw = voronoi_paths(pos[b, idx], goals[b, idx], obstacles[b], agent_radius=agent_radius,
                            obstacle_radius=obstacle_radius, half_size=half_size, margin=margin)
        P = max(len(p) for p in raw) + 1 if raw else 1
        full = np.repeat(np.where(alive[b][:, None], goals[b], pos[b])[:, None], P, axis=1)
        for j, p in zip(idx, raw):
            full[j, : len(p) + 1] = np.concatenate([pos[b, j][None], p])
            full[j, len(p) + 1:] = p[-1]
        # shortcut with the same clearance: obstacles and the other agents
        circ = np.concatenate([obstacles[b], pos[b]])
        circ_r = np.concatenate([np.full(K, obstacle_radius), np.full(N, agent_radius)]) + agent_radius + margin
        radius, cm = _circles(pos[b], goals[b], circ, circ_r, K, margin)
        cm[:, K:] &= alive[b][None]
        per_env.append(shortcut(full, np.broadcast_to(circ, (N,) + circ.shape), radius, cm))
    P = max(p.shape[1] for p in per_env)
    return np.stack([np.concatenate([p, np.repeat(p[:, -1:], P - p.shape[1], 1)], 1) for p in per_env])
