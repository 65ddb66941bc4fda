"""``bench env``: how many agent-steps per second the batched particle world delivers.

Measures :class:`~masp_lite.envs.particle.ParticleWorld` on ``mpe-50`` (50 agents,
30 obstacles, horizon 90) with uniformly random action ids, for 1, 64 and 256 parallel
worlds, and — when the test-only reference ``mpe2`` is installed — PettingZoo's
``simple_spread_v3`` with 50 agents through its parallel API with random actions, *in the
same run*, so that the ratio compares like with like on whatever machine runs it. When
TorchRL is installed (``pip install masp-lite[torchrl]``), the TorchRL face
(:class:`~masp_lite.envs.torchrl.ParticleTorchRLEnv`) is measured too, at the batch size of
the ratio, through ``step_and_maybe_reset`` as TorchRL's collectors step it (observations,
rewards, metrics and auto-resets included); its overhead is its time per step over the native
world's, both timed in alternating blocks of 10 steps in the same process (:func:`measure_torchrl`),
and both rates are printed, so the overhead is their ratio.

What is counted: one agent-step is one agent advanced by one environment step
(``steps × worlds × agents``). Episode resets **are included** in the timed loop (a world
that reaches its horizon is reset, as in training), and so is drawing the random actions.
Each measurement warms up for a few steps, then runs for ``--seconds`` of wall time, split
into ``--rounds`` that alternate between masp-lite, its TorchRL face and mpe2, so a load
change mid-run hits every side alike; each figure is the median over rounds, and every
printed ratio is the ratio of two printed figures.

Threads: ``--threads`` defaults to the product's count for a world's step
(:data:`~masp_lite.threads.EVALUATE_THREADS`, one: a second buys nothing here), and torch's threads
wait passively (:mod:`masp_lite.threads`). Two threads that spin while they wait collapsed 25-50x
when another program kept a core busy, and two runs of this target back to back then disagreed
6x; at one thread, two runs back to back on a loaded machine agreed within 8 % and 17 % (research
log, 2026-12-07). Other programs' CPU use is measured before the run (a warning says when the machine
is busy) and the load average printed after; each printed ratio comes with the range of its
per-round ratios, so a reader sees how far the rounds agreed.

Options: ``--seconds`` per measurement, ``--rounds``, ``--threads`` torch threads (default 1),
``--worlds`` the batch sizes, ``--json PATH`` to also write the figures as JSON.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import time

import torch

from ..envs.particle import NUM_ACTIONS, ParticleWorld
from ..threads import EVALUATE_THREADS
from . import calls_per_second, load_average, write_json
from .competing import busy_warning, other_cpu_use

SCENARIO = "mpe-50"
RATIO_AT = 64  # the batch size at which masp-lite is compared with mpe2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=3.0, help="wall time per measurement (default 3)")
    parser.add_argument("--threads", type=int, default=EVALUATE_THREADS,
                        help=f"torch threads (default {EVALUATE_THREADS}, the product's for a world's step)")
    parser.add_argument("--rounds", type=int, default=5,
                        help="split each measurement into this many alternating rounds (default 5)")
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 64, 256],
                        help="numbers of parallel worlds to measure (default 1 64 256)")
    parser.add_argument("--json", metavar="PATH", default=None, help="also write the results as JSON")


def measure_masp(num_envs: int, seconds: float, seed: int = 0) -> float:
    """Agent-steps/s of ``num_envs`` mpe-50 worlds under random actions (resets included)."""
    world = ParticleWorld(SCENARIO, num_envs=num_envs, seed=seed)
    gen = torch.Generator().manual_seed(seed)
    shape = (num_envs, world.num_agents)

    def one_step():
        world.step(torch.randint(0, NUM_ACTIONS, shape, generator=gen))
        if bool(world.done.any()):
            world.reset()

    return calls_per_second(one_step, seconds) * num_envs * world.num_agents


def measure_torchrl(num_envs: int, seconds: float, seed: int = 0, block: int = 10) -> tuple[float, float] | None:
    """(agent-steps/s of the TorchRL face, of the native world beside it) over ``num_envs`` mpe-50 worlds.

    ``None`` without TorchRL. The face steps through ``step_and_maybe_reset`` (random actions,
    auto-resets), a native world of the same size through ``step`` and ``reset``; the two
    alternate in blocks of ``block`` steps for ``seconds`` of wall time, and each rate comes from
    its median block time, so that other work on the machine slows both sides alike. The
    overhead is the second rate over the first."""
    if importlib.util.find_spec("torchrl") is None:
        return None
    from ..envs.torchrl import ParticleTorchRLEnv

    env = ParticleTorchRLEnv(SCENARIO, num_envs=num_envs, seed=seed)
    world = ParticleWorld(SCENARIO, num_envs=num_envs, seed=seed)
    gen = torch.Generator().manual_seed(seed)
    shape = (num_envs, env.num_agents)
    td = env.reset()

    def face_step():
        nonlocal td
        td.set(("agents", "action"), torch.randint(0, NUM_ACTIONS, shape, generator=gen))
        _, td = env.step_and_maybe_reset(td)

    def native_step():
        world.step(torch.randint(0, NUM_ACTIONS, shape, generator=gen))
        if bool(world.done.any()):
            world.reset()

    def timed(fn):
        start = time.perf_counter()
        for _ in range(block):
            fn()
        return (time.perf_counter() - start) / block

    timed(face_step), timed(native_step)  # warm-up
    face, native, start = [], [], time.perf_counter()
    while time.perf_counter() - start < seconds or not face:
        face.append(timed(face_step))
        native.append(timed(native_step))
    agent_steps = num_envs * env.num_agents
    return agent_steps / statistics.median(face), agent_steps / statistics.median(native)


def measure_mpe2(seconds: float, num_agents: int = 50, horizon: int = 90, seed: int = 0) -> float | None:
    """Agent-steps/s of mpe2's ``simple_spread_v3`` (parallel API, random actions); None without mpe2."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        return None
    env = simple_spread_v3.parallel_env(N=num_agents, max_cycles=horizon)
    env.reset(seed=seed)
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(seed + i)

    def one_step():
        actions = {a: env.action_space(a).sample() for a in env.agents}
        env.step(actions)
        if not env.agents:
            env.reset()

    rate = calls_per_second(one_step, seconds, warmup=1)
    env.close()
    return rate * num_agents


def _spread(ratios) -> str:
    """The lowest and highest of per-round ratios, as ``"low-high"``."""
    ratios = sorted(ratios)
    return f"{ratios[0]:,.2f}-{ratios[-1]:,.2f}"


def run(args: argparse.Namespace) -> int:
    if not args.seconds > 0:
        raise ValueError(f"--seconds: expected a positive number, got {args.seconds}")
    if args.threads < 1 or args.rounds < 1:
        raise ValueError(f"--threads, --rounds: expected positive ints, got {args.threads}, {args.rounds}")
    if any(b < 1 for b in args.worlds):
        raise ValueError(f"--worlds: expected positive ints, got {args.worlds}")
    torch.set_num_threads(args.threads)
    load_before, others = load_average(), other_cpu_use()
    print(f"bench env: {SCENARIO} (50 agents, 30 obstacles), random actions, resets included, "
          f"{args.threads} thread(s), {args.seconds:g} s per measurement in {args.rounds} round(s), "
          f"{os.cpu_count()} CPU(s), load average {load_before}, other programs' CPU use {others}")
    if (warning := busy_warning(others)) is not None:
        print(warning)
    # rounds alternate between the sides, so a load change hits all alike
    share = args.seconds / args.rounds
    masp_rounds = {b: [] for b in args.worlds}
    base = RATIO_AT if RATIO_AT in args.worlds else max(args.worlds)
    ref_rounds, trl_rounds = [], []
    for r in range(args.rounds):
        for b in args.worlds:
            masp_rounds[b].append(measure_masp(b, share, seed=r))
        trl_rounds.append(measure_torchrl(base, share, seed=r))
        ref_rounds.append(measure_mpe2(share, seed=r))
    masp = {b: statistics.median(v) for b, v in masp_rounds.items()}
    for b in args.worlds:
        print(f"  masp-lite  {b:>5} world(s)      {masp[b]:>14,.0f} agent-steps/s")
    trl = overhead = beside = None
    if trl_rounds[0] is None:
        print("  TorchRL not installed: no TorchRL-face measurement")
    else:
        trl = statistics.median(t for t, _ in trl_rounds)
        beside = statistics.median(n for _, n in trl_rounds)
        overhead = beside / trl
        print(f"  TorchRL face {base:>3} world(s)      {trl:>14,.0f} agent-steps/s")
        print(f"  native world beside it         {beside:>14,.0f} agent-steps/s (blocks alternating with the face)")
        print(f"  overhead of the TorchRL face at {base} worlds: {overhead:.2f}x the native world's time "
              f"({beside:,.0f} / {trl:,.0f}; rounds {_spread(n / t for t, n in trl_rounds)})")
    ref = ratio = None
    if ref_rounds[0] is None:
        print("  mpe2 not installed: no reference measurement")
    else:
        ref = statistics.median(ref_rounds)
        print(f"  mpe2 simple_spread_v3 (1 episode) {ref:>14,.0f} agent-steps/s")
        ratio = masp[base] / ref
        print(f"  ratio masp-lite / mpe2 at {base} worlds: {ratio:,.0f}x ({masp[base]:,.0f} / {ref:,.0f}; rounds "
              f"{_spread(m / r for m, r in zip(masp_rounds[base], ref_rounds))})")
    load_after = load_average()
    print(f"  load average after: {load_after}")
    if args.json:
        result = {"target": "env", "scenario": SCENARIO, "num_agents": 50, "resets": "included",
                  "actions": "random", "threads": args.threads, "seconds": args.seconds,
                  "rounds": args.rounds, "cpus": os.cpu_count(),
                  "load_average": {"before": load_before, "after": load_after}, "other_cpu_use": others,
                  "torch": torch.__version__,
                  "masp_agent_steps_per_s": {str(b): v for b, v in masp.items()},
                  "mpe2_agent_steps_per_s": ref,
                  "ratio": None if ratio is None else {"worlds": base, "value": ratio},
                  "torchrl_agent_steps_per_s": trl, "native_beside_torchrl_agent_steps_per_s": beside,
                  "torchrl_overhead": None if overhead is None else {"worlds": base, "value": overhead}}
        write_json(args.json, result)
        print(f"  wrote {args.json}")
    return 0
