"""``python -m masp_lite bench decide``: MASP's decision time per step.

Decision time (the paper's "Execution Efficiency": 14 ms per step for 50 agents): one
world of ``mpe-50`` (``--agents`` changes the team size), both levels — the Goal Matcher
every ``global_step`` steps and the executor every step — timed around
``MASPPolicy.act`` with ``time.perf_counter`` over a whole episode, after one warm-up
episode, on the CPU with ``--threads`` torch threads (default 1, as ``evaluate``: a second buys nothing
for one team's decision, :mod:`masp_lite.threads`); the
process CPU time (``time.process_time``, all threads) is reported too, since on a machine
shared with other work the wall time mostly measures waiting for a core. The mean
over steps is reported, so the Goal Matcher's cost is spread over its period, and the
mean over executor-only steps and Goal Matcher steps separately. The shipped weights are
used when present (timing does not depend on the values of the weights; without them
freshly initialised networks of the same architecture are timed, and the output says so).

Training throughput is ``bench train``'s (:mod:`masp_lite.bench.train`).
"""
from __future__ import annotations

import time

import torch

from ..reproduction.paper import PAPER
from ..threads import EVALUATE_THREADS
from . import load_average, write_json
from .competing import warn_if_busy

__all__ = ["add_arguments", "run", "decision_time", "PAPER_MS"]

PAPER_MS = float(PAPER["per-step-time"]["masp"][0])
"""MASP's per-step time for 50 agents reported in the paper (section "Execution Efficiency")."""


def add_arguments(parser) -> None:
    parser.add_argument("--agents", type=int, default=50, help="team size on mpe-50 (default 50)")
    parser.add_argument("--threads", type=int, default=EVALUATE_THREADS,
                        help=f"torch threads (default {EVALUATE_THREADS}, as evaluate)")
    parser.add_argument("--json", default=None, help="also write the numbers to this JSON file")


def _policy(world):
    from ..nets.masp import MASPNets
    from ..policies.masp import MASPPolicy
    from ..weights import load_weights
    try:
        nets, _ = load_weights(None, scenario="mpe-50")
        source = "shipped mpe-50 weights"
    except ValueError:
        nets, source = MASPNets(), "untrained networks (no shipped mpe-50 weights)"
    nets.eval()
    return MASPPolicy.from_nets(world, nets, seed=0), source


def decision_time(agents: int = 50) -> dict:
    """Mean milliseconds of ``act`` per step of one world; also split by level."""
    from ..envs import make
    world = make("mpe-50", num_envs=1, seed=0, num_agents=agents)
    policy, source = _policy(world)
    times, cpu, gm_step = [], [], []
    for episode in range(2):  # the first episode warms up
        obs = world.reset(seed=episode)
        policy.reset(obs)
        for _ in range(world.horizon):
            due = int(obs["t"][0]) % policy.global_step == 0
            c0, t0 = time.process_time(), time.perf_counter()
            actions = policy.act(obs)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            if episode:
                times.append(dt)
                cpu.append(dc)
                gm_step.append(due)
            obs, _ = world.step(actions)
    t = torch.tensor(times) * 1e3
    due = torch.tensor(gm_step)
    return {"agents": agents, "ms_per_step": float(t.mean()), "ms_executor_only_steps": float(t[~due].mean()),
            "ms_goal_matcher_steps": float(t[due].mean()), "cpu_ms_per_step": float(torch.tensor(cpu).mean() * 1e3),
            "paper_ms": PAPER_MS, "weights": source}


def run(args) -> int:
    for name in ("agents", "threads"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')}: expected a positive int, got {getattr(args, name)}")
    torch.set_num_threads(args.threads)
    load = load_average()
    warn_if_busy()
    res = {"threads": args.threads, "load_average_1min": load, "decide": decision_time(args.agents)}
    d = res["decide"]
    print(f"MASP decision time, {d['agents']} agents, CPU, {args.threads} threads ({d['weights']}):")
    print(f"  {d['ms_per_step']:.2f} ms per step (executor-only steps {d['ms_executor_only_steps']:.2f} ms, "
          f"Goal Matcher steps {d['ms_goal_matcher_steps']:.2f} ms); paper: {PAPER_MS:.0f} ms")
    print(f"  process CPU time {d['cpu_ms_per_step']:.2f} ms per step (all threads; less sensitive to other load)")
    print(f"(1-minute load average at start: {load}; other work on the machine inflates these times)")
    if args.json:
        write_json(args.json, res)
    return 0
