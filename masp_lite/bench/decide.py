"""``python -m masp_lite bench decide``: MASP's decision time per step, and its training throughput.

Decision time (the paper's "Execution Efficiency": 14 ms per step for 50 agents): one
world of ``mpe-50`` (``--agents`` changes the team size), both levels — the Goal Matcher
every ``global_step`` steps and the executor every step — timed around
``MASPPolicy.act`` with ``time.perf_counter`` over a whole episode, after one warm-up
episode, on the CPU with ``--threads`` torch threads (2: the course's laptop); the
process CPU time (``time.process_time``, all threads) is reported too, since on a machine
shared with other work the wall time mostly measures waiting for a core. The mean
over steps is reported, so the Goal Matcher's cost is spread over its period, and the
mean over executor-only steps and Goal Matcher steps separately. The shipped weights are
used when present (timing does not depend on the values of the weights; without them
freshly initialised networks of the same architecture are timed, and the output says so).

Training throughput: environment steps per second of :class:`~masp_lite.algos.masp_trainer.MASPTrainer`
(collection and both PPO updates) on ``mpe-20`` and ``mpe-50`` with the default settings
except ``--train-envs`` worlds, over ``--train-iterations`` iterations after one warm-up.
Machines shared with other work inflate both numbers; the output prints the load average.
"""
from __future__ import annotations

import json
import os
import time

import torch

from ..evaluation.paper import PAPER

__all__ = ["add_arguments", "run", "decision_time", "training_throughput", "PAPER_MS"]

PAPER_MS = float(PAPER["per-step-time"]["masp"][0])
"""MASP's per-step time for 50 agents reported in the paper (section "Execution Efficiency")."""


def add_arguments(parser) -> None:
    parser.add_argument("--agents", type=int, default=50, help="team size on mpe-50 (default 50)")
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--train-iterations", type=int, default=1,
                        help="timed training iterations per scenario (0 skips the throughput part)")
    parser.add_argument("--train-envs", type=int, default=16, help="worlds per training iteration (default 16)")
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


def training_throughput(scenario: str, num_envs: int = 16, iterations: int = 1) -> float:
    """Environment steps per second of MASP training (collect + update) on ``scenario``."""
    from ..algos.masp_trainer import MASPTrainer
    from ..config import RunConfig, TrainConfig
    tr = MASPTrainer(scenario, TrainConfig(run=RunConfig(num_envs=num_envs)), seed=0)
    tr.iteration()  # warm-up
    start, t0 = tr.env_steps, time.perf_counter()
    for _ in range(iterations):
        tr.iteration()
    return (tr.env_steps - start) / (time.perf_counter() - t0)


def run(args) -> int:
    for name in ("agents", "threads", "train_envs"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')}: expected a positive int, got {getattr(args, name)}")
    if args.train_iterations < 0:
        raise ValueError(f"--train-iterations: expected an int >= 0, got {args.train_iterations}")
    torch.set_num_threads(args.threads)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    res = {"threads": args.threads, "load_average_1min": load, "decide": decision_time(args.agents)}
    d = res["decide"]
    print(f"MASP decision time, {d['agents']} agents, CPU, {args.threads} threads ({d['weights']}):")
    print(f"  {d['ms_per_step']:.2f} ms per step (executor-only steps {d['ms_executor_only_steps']:.2f} ms, "
          f"Goal Matcher steps {d['ms_goal_matcher_steps']:.2f} ms); paper: {PAPER_MS:.0f} ms")
    print(f"  process CPU time {d['cpu_ms_per_step']:.2f} ms per step (all threads; less sensitive to other load)")
    if args.train_iterations:
        res["training_env_steps_per_s"] = {}
        for sc in ("mpe-20", "mpe-50"):
            sps = training_throughput(sc, args.train_envs, args.train_iterations)
            res["training_env_steps_per_s"][sc] = sps
            print(f"MASP training throughput on {sc} ({args.train_envs} worlds): {sps:.0f} env steps/s")
    print(f"(1-minute load average at start: {load:.1f}; other work on the machine inflates these times)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)
    return 0
