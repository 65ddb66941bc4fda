"""``bench planners``: planning time per step of the (H) planners at 50 agents, beside the paper's.

The paper's Table "per-step time" measures, in MPE with 50 agents, the time a method
needs per environment step, excluding the environment: (H)ORCA 39 ms, (H)RRT* 456 ms,
(H)Voronoi 44 ms (MASP 14 ms). This target runs ``h-orca``, ``h-rrtstar``, ``h-voronoi``
(and ``h-greedy`` as the floor) on ``mpe-50`` in **one** world (``num_envs=1``, so nothing
is amortized over a batch) for ``--episodes`` full episodes, timing only ``policy.act``
— goal assignment, planning and control, every step.
It prints mean (std) milliseconds per step and the paper's figure beside it.
``--scenario drone-20`` times the drone planners at 20 drones the same way (the geometric
controller included); the paper gives no per-step time for drones, so its column shows "-".

``--split`` also runs ``--split-episodes`` batched episodes per planner on a scenario
(default ``mpe-20``) and splits the collision rate (CR, contacts per step) into
agent–agent and agent–obstacle contacts with
:func:`masp_lite.policies.planners.split_collisions` — the path planners should put
nobody into an obstacle.

Timings depend on the machine and on its load: the machine's load average is printed with
them, and figures measured while other processes compete for the cores are inflated.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from ..envs import get_scenario, make
from ..policies import get_factory, make_policy, method_options
from ..reproduction.paper import PAPER
from . import load_average, write_json
from .competing import warn_if_busy

__all__ = ["add_arguments", "run", "step_times", "collision_split", "PAPER_MS"]

#: The paper's per-step time at 50 agents (ms, mean and std; Table "per-step time").
PAPER_MS = {m: tuple(map(float, PAPER["per-step-time"][m])) for m in ("h-orca", "h-rrtstar", "h-voronoi")}
METHODS = ["h-greedy", "h-orca", "h-rrtstar", "h-voronoi"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--episodes", type=int, default=2, help="timed episodes per method (default 2)")
    parser.add_argument("--scenario", default="mpe-50", help="scenario to time (default mpe-50)")
    parser.add_argument("--methods", nargs="+", default=METHODS, help=f"methods (default {METHODS})")
    parser.add_argument("--seed", type=int, default=0, help="world and policy seed (default 0)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("--split", action="store_true", help="also split CR into agent-agent / agent-obstacle")
    parser.add_argument("--split-scenario", default="mpe-20", help="scenario of --split (default mpe-20)")
    parser.add_argument("--split-episodes", type=int, default=20, help="episodes of --split (default 20)")
    parser.add_argument("--json", default=None, help="also write the figures to this JSON file")


def _policy(method, world, seed):
    named, _ = method_options(get_factory(method))
    return make_policy(method, world, **({"seed": seed} if "seed" in named else {}))


def step_times(method: str, scenario: str = "mpe-50", episodes: int = 2, seed: int = 0) -> np.ndarray:
    """Milliseconds of ``policy.act`` for every step of ``episodes`` episodes in one world."""
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected a positive int, got {episodes!r}")
    world = make(scenario, num_envs=1, seed=seed)
    policy = _policy(method, world, seed)
    out = []
    for _ in range(episodes):
        obs = world.reset()
        policy.reset(obs)
        for _ in range(world.horizon):
            t0 = time.perf_counter()
            actions = policy.act(obs)          # assignment + planning + control: all of it
            out.append(time.perf_counter() - t0)
            obs, _ = world.step(actions)
    return np.asarray(out) * 1e3


def collision_split(method: str, scenario: str = "mpe-20", episodes: int = 20, seed: int = 0) -> dict:
    """Mean contacts per step over ``episodes`` episodes: total, agent–agent, agent–obstacle."""
    from ..policies.planners import split_collisions
    world = make(scenario, num_envs=episodes, seed=seed)
    obs = world.reset(seed=seed)
    policy = _policy(method, world, seed)
    policy.reset(obs)
    aa = ao = 0.0
    for _ in range(world.horizon):
        obs, _ = world.step(policy.act(obs))
        a, o = split_collisions(obs, world.scenario)
        aa, ao = aa + a.double().mean().item(), ao + o.double().mean().item()
    aa, ao = aa / world.horizon, ao / world.horizon
    return {"cr": aa + ao, "agent_agent": aa, "agent_obstacle": ao,
            "obstacle_share": ao / (aa + ao) if aa + ao > 0 else 0.0}


def run(args: argparse.Namespace) -> int:
    torch.set_num_threads(max(1, int(args.threads)))
    load0 = load_average()
    warn_if_busy()
    rows, record = [], {"scenario": args.scenario, "world": get_scenario(args.scenario).world,
                        "episodes": args.episodes, "threads": args.threads}
    print(f"planning time per step, {args.scenario}, one world, {args.episodes} episode(s); "
          f"load average {load0} on {os.cpu_count()} cores")
    print(f"{'method':<11} {'ours ms':>14} {'paper ms':>10} {'paper/ours':>11}")
    for m in args.methods:
        t0 = time.perf_counter()
        ms = step_times(m, args.scenario, args.episodes, args.seed)
        paper = PAPER_MS.get(m) if args.scenario == "mpe-50" else None  # the paper times MPE, N = 50 only
        mean, std = float(ms.mean()), float(ms.std())
        ratio = f"{paper[0] / mean:>10.1f}x" if paper else f"{'-':>11}"
        print(f"{m:<11} {mean:>8.2f} ({std:.2f}) {(f'{paper[0]:.0f} ({paper[1]:.0f})' if paper else '-'):>10} {ratio}"
              f"   [{time.perf_counter() - t0:.0f} s]", flush=True)
        record[m] = {"ms": {"mean": mean, "std": std}, "paper_ms": paper[0] if paper else None}
        rows.append(m)
    record["load_average"] = [load0, load_average()]
    print(f"load average after: {record['load_average'][1]} (timings under load are inflated)")
    if args.split:
        print(f"\ncollisions per step on {args.split_scenario} ({args.split_episodes} episodes)")
        print(f"{'method':<11} {'CR':>7} {'agent-agent':>12} {'agent-obst':>11} {'obst share':>11}")
        record["split"] = {"scenario": args.split_scenario}
        for m in args.methods:
            s = collision_split(m, args.split_scenario, args.split_episodes, args.seed)
            record["split"][m] = s
            print(f"{m:<11} {s['cr']:>7.3f} {s['agent_agent']:>12.3f} {s['agent_obstacle']:>11.3f} "
                  f"{s['obstacle_share']:>10.0%}", flush=True)
    if args.json:
        write_json(args.json, record, indent=1)
    return 0
