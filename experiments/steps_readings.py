"""The paper's Steps, read two ways: every episode (a failed one counts the horizon) or solved episodes only.

Usage (from the repository root)::

    python -m experiments.steps_readings --scenario drone-20 --methods masp-velocity h-orca [--seeds 12345]
        [--episodes 32]

The paper defines Steps as "the average timesteps required to achieve a target Success Rate
per episode" and prints a backslash when no episode reaches SR 1. masp-lite reads it as the
mean over *all* episodes, an episode that never reaches SR 1 counting the horizon
(:mod:`masp_lite.evaluation.metrics`); the backslash rule fits the other reading too, the mean
over the episodes that do reach it. With crashes as failures (drones) the two readings part
ways: this prints both, per method, on the same episodes as ``evaluate`` (same seeds, same
batch), with the episode counts and each method's ratio to the first one. A question about the
metric, not a method: the product keeps its one reading.
"""
from __future__ import annotations

import argparse

from masp_lite.evaluation import evaluate, reached_target, steps


def episode_steps(method: str, scenario: str, seeds: list[int], episodes: int):
    """(Steps per episode, solved per episode) on the episodes ``evaluate`` runs (its own log)."""
    _, log = evaluate(method, scenario, episodes=episodes, seeds=seeds, return_log=True)
    return steps(log).double(), reached_target(log)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="drone-20")
    p.add_argument("--methods", nargs="+", default=["masp-velocity", "h-orca"])
    p.add_argument("--seeds", nargs="+", type=int, default=[12345])
    p.add_argument("--episodes", type=int, default=32, help="episodes per seed")
    args = p.parse_args(argv)
    print(f"{args.scenario}, seeds {args.seeds}, {args.episodes} episodes each")
    print(f"{'method':16s} {'solved':>9s} {'Steps (all)':>12s} {'Steps (solved)':>15s} {'ratio all':>10s} "
          f"{'ratio solved':>13s}")
    first = None
    for m in args.methods:
        st, ok = episode_steps(m, args.scenario, args.seeds, args.episodes)
        every, solved = float(st.mean()), float(st[ok].mean()) if bool(ok.any()) else float("nan")
        first = first or (every, solved)
        print(f"{m:16s} {int(ok.sum()):4d}/{len(ok):<4d} {every:12.2f} {solved:15.2f} {every / first[0]:10.3f} "
              f"{solved / first[1]:13.3f}", flush=True)


if __name__ == "__main__":
    main()
