"""Goal assignment when a team can shrink, and the min-max assignment: the "(H)" methods' rules.

MASP's trainer needs only :mod:`masp_lite.algos.assignment` (the Hungarian reference of
R_GM); the scripted references and the planners (:mod:`masp_lite.policies`) also assign
goals under the paper's varying-team protocols (:data:`TEAM_PROTOCOLS`, :class:`TeamAssignment`),
send the agents a Hungarian assignment leaves without a goal to their nearest one (:func:`hungarian_goals`,
the goals of ``h-mappo``) and, for ``h-bottleneck``, assign by the min-max rule (:func:`bottleneck`). Same conventions
as :mod:`masp_lite.algos.assignment` (masks, rectangular cases, ``-1`` for no goal).
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from .assignment import _as_numpy, _check, _solve, hungarian

__all__ = ["hungarian_random_subset", "hungarian_goals", "bottleneck", "sequential", "TeamAssignment", "TEAM_PROTOCOLS"]


def hungarian_random_subset(agent_pos, goal_pos, agent_mask=None, goal_mask=None,
                            generator=None) -> torch.Tensor:
    """Hungarian assignment after drawing a random subset of goals when goals outnumber agents.

    This is the paper's rule for varying team sizes (section "Varying Team Sizes"): "we
    randomly select a subset of unreached goals matching the agent count at each global
    step". In each world where the available goals outnumber the alive agents, a uniformly
    random subset of the available goals, of the alive-agent count, is drawn first; the
    Hungarian algorithm then assigns the alive agents to that subset (a square problem).
    Worlds with as many or more agents than goals are solved as :func:`hungarian` does.

    ``generator``: a ``torch.Generator`` (CPU) or a ``numpy.random.Generator`` — the only
    source of randomness, so the same generator state gives the same assignment. ``None``
    uses a fresh, unseeded numpy generator.
    """
    a, g, am, gm, device = _check(agent_pos, goal_pos, agent_mask, goal_mask)
    B, L = gm.shape
    if generator is None:
        keys = np.random.default_rng().random((B, L))
    elif isinstance(generator, torch.Generator):
        keys = torch.rand(B, L, generator=generator, dtype=torch.float64).numpy()
    elif isinstance(generator, np.random.Generator):
        keys = generator.random((B, L))
    else:
        raise ValueError(f"generator: expected a torch.Generator or numpy.random.Generator, "
                         f"got {type(generator).__name__}")
    # random order of the available goals; keep the first (number of alive agents) of them
    keys = np.where(gm, keys, np.inf)
    rank = np.argsort(np.argsort(keys, axis=1, kind="stable"), axis=1, kind="stable")
    n_agents = am.sum(1, keepdims=True)
    subset = gm & (rank < n_agents)
    return torch.from_numpy(_solve(a, g, am, subset)).to(device)


def hungarian_goals(agent_pos, goal_pos, agent_mask=None, goal_mask=None) -> torch.Tensor:
    """:func:`~masp_lite.algos.assignment.hungarian`, with every agent it leaves without a goal sent to its nearest one.

    The goals of ``h-mappo`` and of ``masp``'s ``decode="hungarian"`` diagnostic: (B, N)
    goal indices, none ``-1`` (a shrinking team can have more agents than open goals).
    """
    goals = hungarian(agent_pos, goal_pos, agent_mask, goal_mask)
    nearest = torch.cdist(torch.as_tensor(agent_pos), torch.as_tensor(goal_pos)).argmin(-1).to(goals.device)
    return torch.where(goals >= 0, goals, nearest)


def _bottleneck_one(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the min-max assignment of one cost matrix, ties broken by total cost.

    The longest edge of an optimal assignment is one of the matrix's entries, between two
    bounds: every member of the smaller side needs an edge (so at least the largest of
    their shortest edges), and the min-sum assignment is one candidate (so at most its
    longest edge). Binary search over the entries between them for the smallest ``t``
    whose edges ``d <= t`` still hold a matching of size ``min(n_rows, n_cols)`` — true
    when ``linear_sum_assignment`` on the 0/1 matrix ``d > t`` finds a zero-cost
    assignment (a few microseconds, faster here than building a sparse graph for
    Hopcroft–Karp) — then ``linear_sum_assignment`` with the longer edges priced out.
    """
    r, c = linear_sum_assignment(d)
    upper = d[r, c].max()
    lower = (d.min(axis=1) if d.shape[0] <= d.shape[1] else d.min(axis=0)).max()
    values = np.unique(d[(d >= lower) & (d <= upper)])
    lo, hi = 0, len(values) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        over = d > values[mid]
        rr, cc = linear_sum_assignment(over)
        if not over[rr, cc].any():
            hi = mid
        else:
            lo = mid + 1
    if values[lo] == upper:  # the min-sum assignment is already min-max
        return r, c
    big = (d.sum() + 1.0) * 2  # more than any assignment's total within the threshold
    return linear_sum_assignment(np.where(d <= values[lo], d, big))


def bottleneck(agent_pos, goal_pos, agent_mask=None, goal_mask=None) -> torch.Tensor:
    """Min–max ("bottleneck") assignment: the longest agent-to-goal distance as short as possible.

    The Steps metric waits for the *last* landmark, so it follows the longest trip, while
    :func:`hungarian` minimises the total. Among the assignments with the smallest longest
    trip this one has the least total distance. Same conventions as :func:`hungarian`
    (masks, rectangular cases, ``-1`` for no goal); exact, deterministic.

    Two agents, two goals: the total is least with trips 4.24 + 2.24 (longest 4.24), the
    longest trip with 3.61 + 3.16::

    >>> a = torch.tensor([[[0.0, 0.0], [0.0, 2.0]]])
    >>> g = torch.tensor([[[3.0, 3.0], [2.0, 3.0]]])
    >>> hungarian(a, g).tolist(), bottleneck(a, g).tolist()
    ([[0, 1]], [[1, 0]])
    """
    a, g, am, gm, device = _check(agent_pos, goal_pos, agent_mask, goal_mask)
    B, N = am.shape
    out = np.full((B, N), -1, dtype=np.int64)
    for b in range(B):
        rows, cols = np.flatnonzero(am[b]), np.flatnonzero(gm[b])
        if len(rows) == 0 or len(cols) == 0:
            continue
        r, c = _bottleneck_one(cdist(a[b, rows], g[b, cols]))
        out[b, rows[r]] = cols[c]
    return torch.from_numpy(out).to(device)


def sequential(agent_pos, goal_pos, agent_mask, goal_mask, current=None) -> torch.Tensor:
    """Keep each agent's goal until it is reached; give the free agents the goals nobody holds.

    The paper's account of a centralized assignment when the team shrinks (section
    "Goal Matcher": "we need to first assign a part of the goals, and then assign the
    remaining goals"): ``current`` ``None`` is the first assignment, :func:`hungarian` of
    the alive agents over the available goals (``goal_mask``, e.g. not reached yet); with
    ``current`` (B, N) an alive agent keeps a goal that is still available, and the agents
    without one (theirs reached, or none) are assigned by :func:`hungarian` to the available
    goals no kept agent holds — so a goal left over goes to an agent once it has reached
    its own.
    """
    if current is None:
        return hungarian(agent_pos, goal_pos, agent_mask, goal_mask)
    a, g, am, gm, device = _check(agent_pos, goal_pos, agent_mask, goal_mask)
    cur = _as_numpy(current, "current (B, N)", 2).astype(np.int64)
    if cur.shape != am.shape:
        raise ValueError(f"current: expected shape {am.shape}, got {cur.shape}")
    keep = am & (cur >= 0) & np.take_along_axis(gm, np.clip(cur, 0, None), axis=1)
    held = np.zeros_like(gm)
    rows, cols = np.nonzero(keep)
    held[rows, cur[rows, cols]] = True
    free = _solve(a, g, am & ~keep, gm & ~held)
    return torch.from_numpy(np.where(keep, cur, free)).to(device)


TEAM_PROTOCOLS = ("resolve", "random_subset", "sequential")
"""How an "(H)" method assigns goals once a team has shrunk (more landmarks than agents):
``resolve`` — every global step over all unreached landmarks (h-greedy's default);
``random_subset`` — every global step over a random subset of the unreached landmarks, as
many as agents (the paper's section "Varying Team Sizes"; the planners' default);
``sequential`` — once when the team shrinks, then a leftover landmark goes to an agent
only when it has reached its own (the paper's section "Goal Matcher":
:func:`sequential`)."""


class TeamAssignment:
    """The "(H)" goal assignment of a world batch under one of :data:`TEAM_PROTOCOLS`.

    ``assign(obs, current)`` -> (B, N) goal indices. Before a team shrinks, and for fixed
    teams, it is the plain assignment (over the unreached landmarks when the team can
    change, since success counts landmarks ever reached); ``cost``/``power`` as h-greedy's.
    """

    def __init__(self, protocol: str, varying: bool, cost: str = "sum", power: float = 1.0, seed: int = 0):
        if protocol not in TEAM_PROTOCOLS:
            raise ValueError(f"team_protocol: expected one of {list(TEAM_PROTOCOLS)}, got {protocol!r}")
        self.protocol, self.varying, self.cost, self.power, self.seed = protocol, varying, cost, power, seed
        self.reset()

    def reset(self) -> None:
        self.generator = torch.Generator().manual_seed(self.seed)
        self._sequential = None  # (B,) bool: worlds whose post-shrink assignment has been made

    def _plain(self, obs, goal_mask):
        if self.cost == "bottleneck":
            return bottleneck(obs["agent_pos"], obs["landmark_pos"], obs["alive"], goal_mask)
        return hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], goal_mask, self.power)

    def assign(self, obs, current=None) -> torch.Tensor:
        if not self.varying:
            return self._plain(obs, None)
        unreached = ~obs["reached"]
        if self.protocol == "random_subset":
            return hungarian_random_subset(obs["agent_pos"], obs["landmark_pos"], obs["alive"], unreached,
                                           generator=self.generator)
        plain = self._plain(obs, unreached)
        if self.protocol == "resolve":
            return plain
        shrunk = ~obs["alive"].all(-1)
        started = shrunk & (torch.zeros_like(shrunk) if self._sequential is None else self._sequential)
        self._sequential = shrunk
        if current is None or not bool(started.any()):  # no world past its first post-shrink assignment
            return plain  # the first assignment after the shrink is the plain one over the unreached
        later = sequential(obs["agent_pos"], obs["landmark_pos"], obs["alive"], unreached, current)
        return torch.where(started.unsqueeze(-1), later, plain)
