"""How do MASP's drone-on-drone crashes look: would the real, flat frames have touched?

Usage (from the repository root)::

    python -m experiments.drone_crashes [--scenario drone-20] [--episodes 16] [--seed 12345] [--checkpoint PATH]
        [--method masp-velocity]

The world makes each drone a collision sphere of radius ``COLLISION_RADIUS`` (arm + rotor =
0.27 m), so two drones crash whenever their centres come within 0.54 m, at any relative
height. The real frame is a flat "+" of rotor discs a few centimetres thick. This runs the
shipped MASP (deterministic) on validation episodes and, for every drone that leaves the
episode, looks at the step before: the nearest other drone, their horizontal and vertical
centre distances, their closing speed, each one's speed, and whether the other one crashed too.
It prints one row per crash and a summary: how many crashes had a vertical separation above
``--flat`` metres (default 0.1: two discs 4 cm thick, tilted a little), i.e. would not have
been contacts between flat frames. A question about the world's crash rule, not a method.
"""
from __future__ import annotations

import argparse

import numpy as np
import torch

from masp_lite.envs import make
from masp_lite.envs.drone_model import COLLISION_RADIUS
from masp_lite.evaluation.rollouts import rollout
from masp_lite.policies import make_policy


def crash_rows(prev: dict, now: dict, keep: int) -> list[dict]:
    """One dict per drone alive in ``prev`` and gone in ``now`` (first ``keep`` worlds), described at ``prev``."""
    pos, vel = prev["agent_pos"].double(), prev["agent_vel"].double()
    was, left = prev["alive"], prev["alive"] & ~now["alive"]
    rows = []
    for b, i in left[:keep].nonzero().tolist():
        others = was[b].clone()
        others[i] = False
        if not bool(others.any()):
            continue
        rel = pos[b] - pos[b, i]                                          # (N, 3): p_j - p_i
        d = rel.norm(dim=-1).masked_fill(~others, float("inf"))
        j = int(d.argmin())
        closing = float(-(rel[j] @ (vel[b, j] - vel[b, i])) / d[j])
        rows.append({"world": b, "drone": i, "other": j, "dist": float(d[j]),
                     "horizontal": float(rel[j, :2].norm()), "vertical": abs(float(rel[j, 2])),
                     "closing": closing, "speed": float(vel[b, i].norm()), "other_speed": float(vel[b, j].norm()),
                     "both": bool(left[b, j]), "height": float(pos[b, i, 2])})
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_crashes", description=__doc__.split("\n")[0])
    p.add_argument("--scenario", default="drone-20")
    p.add_argument("--episodes", type=int, default=16)
    p.add_argument("--seed", type=int, default=12345, help="evaluation seed (validation: not 0-2)")
    p.add_argument("--checkpoint", default=None)
    p.add_argument("--method", default="masp", choices=("masp", "masp-velocity"))
    p.add_argument("--flat", type=float, default=0.1, help="vertical separation (m) above which flat frames miss")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    world = make(args.scenario, num_envs=min(args.episodes, 16))
    policy = make_policy(args.method, world, **({"checkpoint": args.checkpoint} if args.checkpoint else {}))
    rows, last = [], {}

    def on_step(obs, keep):
        if last and int(obs["t"].max()) > 1:
            rows.extend(crash_rows(last, obs, keep))
        last.update({k: obs[k].clone() for k in ("agent_pos", "agent_vel", "alive")})

    log, _ = rollout(world, policy, args.episodes, seed=args.seed, on_step=on_step)
    print(f"{args.scenario}, {args.episodes} episodes (seed {args.seed}): {len(rows)} drones left the episode")
    print("  dist  horiz  vert  closing  speed  other  both  height")
    for r in rows:
        print(f"  {r['dist']:.2f}  {r['horizontal']:.2f}  {r['vertical']:.2f}  {r['closing']:7.2f}  {r['speed']:5.2f}  "
              f"{r['other_speed']:5.2f}  {'yes' if r['both'] else 'no ':>4}  {r['height']:.2f}")
    contact = [r for r in rows if r["dist"] < 2 * COLLISION_RADIUS + 0.2]
    flat_miss = [r for r in contact if r["vertical"] > args.flat]
    median = float(np.median([r["vertical"] for r in contact])) if contact else float("nan")
    print(f"near another drone (centres < {2 * COLLISION_RADIUS + 0.2:.2f} m): {len(contact)}; of those, vertical "
          f"separation > {args.flat} m: {len(flat_miss)}; median vertical {median:.2f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
