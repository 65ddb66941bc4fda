"""Goal assignment with the Hungarian algorithm, batched over worlds.

The paper (section "Goal Assignment", Kuhn 1955) uses the Hungarian algorithm twice: as
the reference the Goal Matcher's reward ``R_GM`` compares against, and as the "(H)"
goal assignment of the planning baselines. Here it is scipy's
``scipy.optimize.linear_sum_assignment`` on the Euclidean distances between agents and
goals, one call per world. Nothing about the algorithm is hand-written; this module only
handles the masks (dropped agents, reached goals), the rectangular cases, and the
conversion between batched torch tensors and numpy. The assignments of the scripted
references, planners and learned goal sources when a team shrinks (random subsets,
keep-until-reached, agents left without a goal sent to their nearest, the min-max assignment)
live beside it, in :mod:`masp_lite.algos.team`.

Conventions, for every function here:

* ``agent_pos`` is (B, N, d) and ``goal_pos`` (B, L, d), any dimension ``d`` (2 for the
  particle world, 3 for drones); torch tensors or numpy arrays.
* ``agent_mask`` (B, N) and ``goal_mask`` (B, L) are bool; ``True`` means the agent is in
  the team (alive) or the goal is available. ``None`` means all.
* The result is a ``torch.long`` tensor (B, N) on ``agent_pos``'s device: the index of the
  goal given to each agent, or ``-1`` for an agent that gets none (masked out, or an
  extra agent when there are more agents than goals).

Rectangular problems are scipy's own: with fewer agents than goals every agent gets a
distinct goal and the chosen subset of goals is the one of least total distance; with
more agents than goals every goal gets one agent and the extra agents get ``-1``.

Example — two agents, three goals on a line; the far goal stays free::

    >>> a = torch.tensor([[[0.0, 0.0], [1.0, 0.0]]])
    >>> g = torch.tensor([[[5.0, 0.0], [1.1, 0.0], [0.1, 0.0]]])
    >>> hungarian(a, g).tolist()
    [[2, 1]]
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

__all__ = ["hungarian", "assignment_cost", "distance_matrix", "check_power"]


def _as_numpy(x, name: str, ndim: int) -> np.ndarray:
    if torch.is_tensor(x):
        x = x.detach().cpu().numpy()
    try:
        arr = np.asarray(x)
    except Exception:  # pragma: no cover - exotic inputs
        raise ValueError(f"{name}: expected a tensor or array, got {type(x).__name__}") from None
    if arr.ndim != ndim:
        raise ValueError(f"{name}: expected a {ndim}-d tensor, got shape {tuple(arr.shape)}")
    return arr


def _check(agent_pos, goal_pos, agent_mask, goal_mask):
    """Validate shapes; return numpy positions (float64), masks (bool) and the output device."""
    device = agent_pos.device if torch.is_tensor(agent_pos) else torch.device("cpu")
    a = _as_numpy(agent_pos, "agent_pos (B, N, d)", 3).astype(np.float64, copy=False)
    g = _as_numpy(goal_pos, "goal_pos (B, L, d)", 3).astype(np.float64, copy=False)
    if a.shape[0] != g.shape[0] or a.shape[2] != g.shape[2]:
        raise ValueError(f"agent_pos {tuple(a.shape)} and goal_pos {tuple(g.shape)}: expected the same "
                         "batch size B and point dimension d")
    B, N, L = a.shape[0], a.shape[1], g.shape[1]
    masks = []
    for m, name, shape in ((agent_mask, "agent_mask", (B, N)), (goal_mask, "goal_mask", (B, L))):
        if m is None:
            masks.append(np.ones(shape, dtype=bool))
            continue
        m = _as_numpy(m, f"{name} {shape}", 2)
        if m.dtype != np.bool_ or m.shape != shape:
            raise ValueError(f"{name}: expected a bool tensor of shape {shape}, got {tuple(m.shape)} {m.dtype}")
        masks.append(m)
    return a, g, masks[0], masks[1], device


def distance_matrix(agent_pos: np.ndarray, goal_pos: np.ndarray) -> np.ndarray:
    """Euclidean distances (B, N, L) between every agent and every goal of each world.

    This is the cost matrix the Hungarian algorithm minimises, for the whole batch at
    once (numpy arrays in and out). :func:`hungarian` itself computes it world by world
    with ``scipy.spatial.distance.cdist`` on the masked points only, which is faster.
    """
    return np.sqrt(((agent_pos[:, :, None, :] - goal_pos[:, None, :, :]) ** 2).sum(-1))


def check_power(power) -> float:
    """``power`` as a float; a clear error unless it is a positive finite number (not a bool)."""
    if isinstance(power, bool) or not isinstance(power, (int, float)) or not (0 < power < float("inf")):
        raise ValueError(f"power: expected a positive number, got {power!r}")
    return float(power)


def _solve(a: np.ndarray, g: np.ndarray, amask: np.ndarray, gmask: np.ndarray, power: float = 1.0) -> np.ndarray:
    """One ``linear_sum_assignment`` per world on the masked distances (to ``power``); -1 where unassigned.

    Distances come from ``scipy.spatial.distance.cdist`` on the masked points of each
    world, which is several times faster than one broadcast over the whole batch.
    """
    B, N = amask.shape
    out = np.full((B, N), -1, dtype=np.int64)
    for b in range(B):  # the only Python loop: scipy solves one matrix at a time
        rows, cols = np.flatnonzero(amask[b]), np.flatnonzero(gmask[b])
        if len(rows) == 0 or len(cols) == 0:
            continue
        d = cdist(a[b, rows], g[b, cols])
        r, c = linear_sum_assignment(d if power == 1.0 else d**power)
        out[b, rows[r]] = cols[c]
    return out


def hungarian(agent_pos, goal_pos, agent_mask=None, goal_mask=None, power: float = 1.0) -> torch.Tensor:
    """Minimum-total-distance assignment of available goals to alive agents, per world.

    Returns a long tensor (B, N): goal index per agent, ``-1`` for none (see the module
    docstring for the rectangular cases). Deterministic: scipy's solver has no randomness.

    ``power``: the cost of a pair is ``distance ** power``. ``1`` (default) minimises the
    total distance. ``2`` minimises the sum of squared distances (Turpin et al.'s goal
    assignment for interchangeable robots), which penalises one long trip more than several
    short ones. It lowers the longest trip, and with it the time until every goal is
    covered (the Steps metric).
    """
    a, g, am, gm, device = _check(agent_pos, goal_pos, agent_mask, goal_mask)
    return torch.from_numpy(_solve(a, g, am, gm, check_power(power))).to(device)


def assignment_cost(agent_pos, goal_pos, assignment, power: float = 1.0) -> torch.Tensor:
    """Total agent-to-goal distance of an assignment, per world: a float tensor (B,).

    ``power``: sum ``distance ** power`` instead (the cost :func:`hungarian` minimises with
    the same ``power``).

    The result has ``agent_pos``'s dtype and device when it is a float tensor (float64 otherwise).

    ``assignment`` (B, N) holds goal indices, ``-1`` for agents without a goal (they add
    nothing). This is the paper's ``D_h`` (Hungarian) or ``D_m`` (Goal Matcher) in ``R_GM``.
    """
    like = agent_pos if torch.is_tensor(agent_pos) and agent_pos.is_floating_point() else None
    a = _as_numpy(agent_pos, "agent_pos (B, N, d)", 3).astype(np.float64, copy=False)
    g = _as_numpy(goal_pos, "goal_pos (B, L, d)", 3).astype(np.float64, copy=False)
    idx = _as_numpy(assignment, "assignment (B, N)", 2)
    if not np.issubdtype(idx.dtype, np.integer) or idx.shape != a.shape[:2]:
        raise ValueError(f"assignment: expected an integer tensor of shape {a.shape[:2]}, "
                         f"got {tuple(idx.shape)} {idx.dtype}")
    if a.shape[0] != g.shape[0] or a.shape[2] != g.shape[2]:
        raise ValueError(f"agent_pos {tuple(a.shape)} and goal_pos {tuple(g.shape)}: expected the same "
                         "batch size B and point dimension d")
    if idx.size and (idx.min() < -1 or idx.max() >= g.shape[1]):
        raise ValueError(f"assignment: expected goal indices in [-1, {g.shape[1]}), got values outside")
    safe = np.clip(idx, 0, None)
    target = np.take_along_axis(g, safe[..., None], axis=1) if g.shape[1] else np.zeros_like(a)
    power = check_power(power)
    dist = np.linalg.norm(a - target, axis=-1)
    dist = (dist if power == 1.0 else dist**power) * (idx >= 0)
    out = torch.from_numpy(dist.sum(1))
    return out if like is None else out.to(like.device, like.dtype)
