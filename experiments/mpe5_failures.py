"""Why SR stays below 0.99 on mpe-5: a lower bound on Steps and a count of the misses.

Usage (from the repository root)::

    python -m experiments.mpe5_failures [--method masp] [--scenario mpe-5] [--set key=value ...]

Part 1, ``T*``: for every evaluation episode (seeds 0 1 2, 100 episodes each, the spawns
of ``evaluate``) the fewest steps after which the agents could have every landmark within
reach, ignoring contacts. It uses MPE's exact dynamics from
rest with axis-aligned pushes: a push at step ``s`` of ``T`` moves the agent
``0.2 (1 - 0.75 ** (T - 1 - s))`` m along its axis by the end, so after ``T`` steps the
agent lies in ``[-X, X] x [-Y, Y]`` for some split of the ``T`` steps into x-pushes
(sum ``X``) and y-pushes (sum ``Y``). A landmark is reachable in ``T`` steps only if it
lies within reach (0.15 m) of such a box. One agent may cover several landmarks at once
only if they lie pairwise within twice the reach. ``T*`` is the first ``T`` at which some
map from landmarks to agents obeys both conditions (all ``N ** N`` maps are tried; for
``N > 6`` a perfect matching of reachable pairs, scipy's ``maximum_bipartite_matching``,
stands in and ignores shared coverage). Both are necessary conditions, so ``T*`` bounds
every method's Steps from below — in mpe2's update order, the world these findings were made
in (``--set integration=mpe2 --set landmark_spawn=whole``; the presets are now the paper's
world, where a push moves the agent one step earlier and ``T*`` is not this bound).

Part 2: every landmark uncovered at the end of an episode, sorted by what happened to it:
never covered, with or without an obstacle across the straight line from its agent's
final position (see :func:`blocked`); covered, then left after the method switched that agent's goal; left
within a step of a contact; left with neither (the agent drove off or overshot).
Only the planners (``assignment``) and MASP (``goals``) expose goals; others count as
"no switch".

Part 3: the share of landmarks missed by where the landmark lies (:func:`landmark_geometry`):
how close its nearest other landmark is (two agents on landmarks under 0.3 m apart must not
both sit on the centres, which are closer than two agent radii plus a margin) and how close
its nearest obstacle's centre is (under 0.25 m an agent on the landmark's centre touches the
obstacle; it has to cover it from the far side of the reach disc).
"""
from __future__ import annotations

import argparse
import itertools
from collections import Counter

import numpy as np
import torch
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from masp_lite.envs import PHYSICS, make
from masp_lite.evaluation import rollout, steps, success_rate
from masp_lite.policies import build_policy, get_factory, method_options


def push_front(T: int) -> tuple[np.ndarray, np.ndarray]:
    """Pareto front of (X, Y) over all splits of ``T`` pushes between the two axes."""
    c = 1 - PHYSICS["damping"]
    gain = PHYSICS["sensitivity"] * PHYSICS["dt"] ** 2 / PHYSICS["mass"] / PHYSICS["damping"]
    s = np.arange(T)
    move = gain * (1 - c ** (T - 1 - s))
    masks = np.arange(2 ** T)
    X = ((masks[:, None] >> s) & 1).astype(np.float64) @ move
    Y = move.sum() - X
    order = np.argsort(-X)
    X, Y = X[order], Y[order]
    keep = Y > np.maximum.accumulate(np.concatenate([[-1.0], Y[:-1]]))
    return X[keep], Y[keep]


def t_star(agent_pos: np.ndarray, landmark_pos: np.ndarray, reach: float, horizon: int) -> np.ndarray:
    """(E,) lower bound on the steps to cover every landmark (``horizon + 1``: not within it)."""
    E, N = agent_pos.shape[:2]
    d = np.abs(agent_pos[:, :, None, :] - landmark_pos[:, None, :, :])
    near = np.linalg.norm(landmark_pos[:, :, None] - landmark_pos[:, None], axis=-1) <= 2 * reach
    maps = np.array(list(itertools.product(range(N), repeat=N))) if N <= 6 else None   # landmark -> agent
    if maps is not None:
        li, lj = np.triu_indices(N, 1)
        shared = maps[:, li] == maps[:, lj]                                  # (maps, pairs)
    out = np.full(E, horizon + 1)
    for T in range(1, horizon + 1):
        FX, FY = push_front(T)
        gap = np.hypot(np.maximum(d[..., 0, None] - FX, 0), np.maximum(d[..., 1, None] - FY, 0))
        ok = (gap <= reach).any(-1)                                          # (E, agent, landmark)
        for e in np.flatnonzero(out > horizon):
            if maps is None:
                found = (maximum_bipartite_matching(csr_matrix(ok[e].astype(np.int8)),
                                                    perm_type="column") >= 0).all()
            else:
                reachable = ok[e][maps, np.arange(N)].all(-1)
                apart = (shared & ~near[e][li, lj]).any(-1)
                found = bool((reachable & ~apart).any())
            if found:
                out[e] = T
    return out


def landmark_geometry(landmark_pos: torch.Tensor, obstacle_pos: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(E, L) distances from each landmark to its nearest other landmark and nearest obstacle centre.

    ``inf`` where there is no other landmark or no obstacle.
    """
    E, L = landmark_pos.shape[:2]
    dl = torch.cdist(landmark_pos, landmark_pos)
    dl = dl.masked_fill(torch.eye(L, dtype=torch.bool), float("inf"))
    if obstacle_pos.shape[1] == 0:
        return dl.min(-1).values, torch.full((E, L), float("inf"), dtype=landmark_pos.dtype)
    return dl.min(-1).values, torch.cdist(landmark_pos, obstacle_pos).min(-1).values


def goal_agent(goals, e: int, lm: int) -> int | None:
    """The first agent of world ``e`` whose goal is landmark ``lm`` (``None``: no goals, or nobody's)."""
    if goals is None or not bool((goals[e] == lm).any()):
        return None
    return int(torch.nonzero(goals[e] == lm).flatten()[0])


def blocked(world, e: int, lm: int, goals) -> bool:
    """An obstacle lies across the straight line from the landmark's agent to the landmark.

    The landmark's agent is the one whose goal it is at the last decision (the nearest
    agent when the method exposes no goals); "across" means the obstacle's centre is within
    ``agent_radius + obstacle_radius`` of the segment from the agent to the landmark.
    """
    sc = world.scenario
    pos, target = world.agent_pos[e], world.landmark_pos[e, lm]
    k = goal_agent(goals, e, lm)
    if k is None:
        k = int((pos - target).norm(dim=-1).argmin())
    a, seg = pos[k], target - pos[k]
    obst = world.obstacle_pos[e]
    if obst.shape[0] == 0:
        return False
    t = ((obst - a) @ seg / seg.dot(seg).clamp(min=1e-12)).clamp(0, 1)
    gap = (a + t[:, None] * seg - obst).norm(dim=-1)
    return bool((gap < sc.agent_radius + sc.obstacle_radius).any())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--method", default="masp")
    p.add_argument("--scenario", default="mpe-5")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="method option, e.g. checkpoint=runs/x/weights.pt")
    a = p.parse_args(argv)
    opts = dict(kv.split("=", 1) for kv in a.set)
    factory = get_factory(a.method)
    tstars, srs, step_counts, kinds = [], [], [], Counter()
    near_lm, near_obst, missed = [], [], []
    for seed in (0, 1, 2):
        world = make(a.scenario, num_envs=100, seed=seed)
        o = dict(opts)
        if "seed" in method_options(factory)[0]:
            o.setdefault("seed", seed)
        policy = build_policy(factory, a.method, world, o)
        goals, act = [], policy.act

        def act_and_log(obs, act=act, policy=policy):
            actions = act(obs)
            g = getattr(policy, "goals", getattr(policy, "assignment", None))
            goals.append(None if g is None else g.clone())
            return actions
        policy.act = act_and_log
        cov, con = [], []
        start = world.reset(seed=seed)
        reach = world.scenario.agent_radius + world.scenario.landmark_radius
        tstars.append(t_star(start["agent_pos"].numpy(), start["landmark_pos"].numpy(), reach, world.horizon))

        def on_step(obs, keep):
            cov.append(obs["covered"].clone())
            con.append(world.info()["agent_collisions"].clone())
        log, _ = rollout(world, policy, 100, seed, on_step=on_step)
        srs.append(success_rate(log).numpy())
        step_counts.append(steps(log).numpy())
        C, K = torch.stack(cov, 1), torch.stack(con, 1)          # (E, T, L), (E, T, N) after each step
        dl, do = landmark_geometry(world.landmark_pos, world.obstacle_pos)
        near_lm.append(dl.flatten().numpy())
        near_obst.append(do.flatten().numpy())
        missed.append((~C[:, -1]).flatten().numpy())
        for e in range(C.shape[0]):
            for lm in torch.nonzero(~C[e, -1]).flatten().tolist():
                if not C[e, :, lm].any():
                    kinds["never covered, " + ("obstacle in the way" if blocked(world, e, lm, goals[-1])
                                               else "open line")] += 1
                    continue
                t = int(torch.nonzero(C[e, :, lm]).flatten().max())  # last step index it was covered
                # the agent that covered it: the one whose goal it was at the next decision
                k = goal_agent(goals[t + 1], e, lm) if t + 1 < len(goals) else None
                later = [g[e] for g in goals[t + 1:] if g is not None]
                if k is not None and any(bool(g[k] != lm) for g in later):
                    kinds["left after a goal switch"] += 1
                elif k is not None and bool((K[e, t:t + 2, k] > 0).any()):
                    kinds["left after a contact"] += 1
                elif k is None:
                    kinds["left, agent unknown"] += 1
                else:
                    kinds["left, no switch, no contact"] += 1
    ts, sr, st = np.concatenate(tstars), np.concatenate(srs), np.concatenate(step_counts)
    print(f"{a.method} on {a.scenario}: SR {sr.mean():.3f}, Steps {st.mean():.2f}; "
          f"lower bound T*: mean {ts.mean():.2f}")
    print(" T*  episodes  Steps  SR     episodes with SR < 1")
    for T in np.unique(ts):
        m = ts == T
        print(f"{T:3d}  {m.sum():8d}  {st[m].mean():5.2f}  {sr[m].mean():.3f}  {(sr[m] < 1).sum():d}")
    print("uncovered at the end:", sum(kinds.values()), dict(kinds))
    miss, dl, do = np.concatenate(missed), np.concatenate(near_lm), np.concatenate(near_obst)
    for name, dist, edges in (("nearest other landmark", dl, [0, 0.3, 0.5, 1.0, np.inf]),
                              ("nearest obstacle centre", do, [0, 0.25, 0.3, 0.4, 0.6, np.inf])):
        print(f"missed / landmarks by {name} (m):")
        for lo, hi in zip(edges[:-1], edges[1:]):
            m = (dist >= lo) & (dist < hi)
            print(f"  [{lo:.2f}, {hi:.2f}): {miss[m].sum():3d} / {m.sum():4d} = {miss[m].mean() if m.any() else 0:.3f}")
    hard, far = (dl < 0.3) | (do < 0.25), (dl >= 0.5) & (do >= 0.5)
    print(f"missed with another landmark under 0.3 m or an obstacle centre under 0.25 m: "
          f"{miss[hard].sum()} of {miss.sum()}; with both over 0.5 m: {miss[far].sum()} / {far.sum()}")


if __name__ == "__main__":
    main()
