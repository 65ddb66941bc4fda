"""``bench busy``: the hot loops beside a competing busy program, as a ratio to the same loops without it.

A learner's laptop always runs something beside the course (a browser, JupyterLab). This target
measures what that costs the three loops the course spends its time in:

===========  ==================================================================================
``world``    one step of ``--worlds`` (64) ``mpe-50`` worlds under random actions, resets included
``decide``   one MASP decision (``act``, both levels) for one team of 50 on ``mpe-50``, world steps untimed
``train``    one MASP training iteration on ``mpe-20`` (``--train-worlds`` worlds, the from-scratch recipe)
===========  ==================================================================================

each at the product's own thread count (:mod:`masp_lite.threads`: one thread, as ``evaluate`` and
``train``; ``--threads`` sets another count for all), with
torch's threads waiting as the product makes them wait (passively, unless torch was imported first).

Idle and busy repetitions interleave: each of ``--rounds`` rounds times the loop for ``--seconds`` (at
least one call) without the competitor and for as long with it (the order alternating between rounds),
the competitor being a process that spins on one CPU in a session of its own
(:func:`~masp_lite.bench.competing.competing_process`). Each round gives one ratio busy / idle of the
calls per second; the printed ratio is their median, so a change in other load between rounds cancels.
On a machine with more than ``--cpus`` (2) CPUs the bench and its competitor are kept on 2 of them
(Linux), since one busy program competes with nothing on a many-core machine: the figures are a 2-core
laptop's. The goal is a ratio of at least 0.8 for every loop; two spinning threads, torch's default,
measured about 0.03 for the world. On a quiet 2-core machine the defaults read 1.00 (world), 0.98 (decide)
and 1.01 (train) (research log, 2026-12-07). A machine already busy before the bench starts makes the ratios
lower (and the target says so first).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import torch

from ..envs.particle import NUM_ACTIONS, ParticleWorld
from ..threads import EVALUATE_THREADS, TRAIN_THREADS, WAIT_POLICY_ENV, passive_wait
from . import write_json
from .competing import busy_warning, competing_process, other_cpu_use, pinned

__all__ = ["add_arguments", "run", "LOOPS", "GOAL", "interleaved_ratio"]

#: loop -> (what it times, the product's thread count for it)
LOOPS = {
    "world": ("world step, mpe-50 x {worlds} worlds", EVALUATE_THREADS),
    "decide": ("MASP decision, N = 50, one team", EVALUATE_THREADS),
    "train": ("MASP training iteration, mpe-20 x {train_worlds} worlds", TRAIN_THREADS),
}
#: The least busy / idle ratio the product's defaults should keep.
GOAL = 0.8


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--loops", nargs="+", default=list(LOOPS), choices=list(LOOPS),
                        help=f"which loops (default: {' '.join(LOOPS)})")
    parser.add_argument("--seconds", type=float, default=0.5,
                        help="wall time per repetition, idle and busy each (default 0.5; at least one call)")
    parser.add_argument("--rounds", type=int, default=5, help="idle/busy pairs per loop (default 5)")
    parser.add_argument("--threads", type=int, default=None,
                        help=f"one torch thread count for every loop (default: the product's, "
                             f"{EVALUATE_THREADS} for world and decide, {TRAIN_THREADS} for train)")
    parser.add_argument("--worlds", type=int, default=64, help="worlds of the world loop (default 64)")
    parser.add_argument("--train-worlds", type=int, default=8, help="worlds of the training loop (default 8)")
    parser.add_argument("--cpus", type=int, default=2,
                        help="keep the bench and its competitor on this many CPUs (Linux; default 2, a laptop's)")
    parser.add_argument("--json", metavar="PATH", default=None, help="also write the results as JSON")


def _world_loop(worlds: int):
    world = ParticleWorld("mpe-50", num_envs=worlds, seed=0)
    gen = torch.Generator().manual_seed(0)

    def call() -> float:
        t0 = time.perf_counter()
        world.step(torch.randint(0, NUM_ACTIONS, (worlds, world.num_agents), generator=gen))
        if bool(world.done.any()):
            world.reset()
        return time.perf_counter() - t0
    return call


def _decide_loop():
    from ..envs import make
    from .decide import _policy
    world = make("mpe-50", num_envs=1, seed=0)
    policy, _ = _policy(world)
    state = {"obs": world.reset(seed=0)}
    policy.reset(state["obs"])

    def call() -> float:
        t0 = time.perf_counter()
        actions = policy.act(state["obs"])
        dt = time.perf_counter() - t0
        state["obs"], _ = world.step(actions)
        if bool(world.done.any()):
            state["obs"] = world.reset()
            policy.reset(state["obs"])
        return dt
    return call


def _train_loop(worlds: int):
    from ..algos.masp_trainer import MASPTrainer
    from ..config import TrainConfig
    from ..recipes import FROM_SCRATCH
    from .train import METHODS
    trainer = MASPTrainer("mpe-20", TrainConfig.from_flat({**FROM_SCRATCH, **METHODS["masp"], "num_envs": worlds}),
                          seed=0)

    def call() -> float:
        t0 = time.perf_counter()
        trainer.iteration()
        return time.perf_counter() - t0
    return call


def _rate(call, seconds: float) -> float:
    """Calls per second of timed work, over at least ``seconds`` of wall time and at least one call."""
    timed, n, start = 0.0, 0, time.perf_counter()
    while n == 0 or time.perf_counter() - start < seconds:
        timed += call()
        n += 1
    return n / timed


def interleaved_ratio(call, seconds: float, rounds: int, competitor=competing_process) -> dict:
    """Idle and busy repetitions of ``call`` interleaved: each round's ratio busy / idle and their median.

    ``competitor()`` is the context in which a repetition is busy. Rounds alternate which side goes
    first, so a slow drift in other load weighs on both alike."""
    call()  # warm-up
    idle, busy = [], []
    for r in range(rounds):
        for side in (("idle", "busy") if r % 2 == 0 else ("busy", "idle")):
            if side == "idle":
                idle.append(_rate(call, seconds))
            else:
                with competitor():
                    busy.append(_rate(call, seconds))
    ratios = [b / i for b, i in zip(busy, idle)]
    return {"idle_per_s": statistics.median(idle), "busy_per_s": statistics.median(busy),
            "ratio": statistics.median(ratios), "ratios": ratios}


def run(args: argparse.Namespace) -> int:
    if not args.seconds > 0:
        raise ValueError(f"--seconds: expected a positive number, got {args.seconds}")
    for name in ("rounds", "worlds", "train_worlds", "cpus"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')}: expected a positive int, got {getattr(args, name)}")
    if args.threads is not None and args.threads < 1:
        raise ValueError(f"--threads: expected a positive int, got {args.threads}")
    use = other_cpu_use()
    saved_threads = torch.get_num_threads()
    rows = {}
    with pinned(args.cpus) as cpus:
        print(f"bench busy: each loop without and with a competing busy process, {args.rounds} interleaved rounds "
              f"of {args.seconds:g} s; {cpus} CPU(s) in use of {os.cpu_count()}; torch threads wait "
              f"{'passively' if passive_wait() else 'actively (spinning)'} ({WAIT_POLICY_ENV}="
              f"{os.environ.get(WAIT_POLICY_ENV, 'unset')}); other programs' CPU use before: {use}")
        if (warning := busy_warning(use)) is not None:
            print(warning)
        try:
            for name in args.loops:
                what, default_threads = LOOPS[name]
                threads = args.threads or default_threads
                torch.set_num_threads(threads)
                call = {"world": lambda: _world_loop(args.worlds), "decide": _decide_loop,
                        "train": lambda: _train_loop(args.train_worlds)}[name]()
                r = interleaved_ratio(call, args.seconds, args.rounds)
                rows[name] = {"what": what.format(worlds=args.worlds, train_worlds=args.train_worlds),
                              "threads": threads, **r}
                verdict = "ok" if r["ratio"] >= GOAL else f"below {GOAL}"
                print(f"  {name:<7} {rows[name]['what']:<48} {threads} thread(s): idle {r['idle_per_s']:9.1f}/s  "
                      f"busy {r['busy_per_s']:9.1f}/s  busy/idle {r['ratio']:.2f} ({verdict}; rounds "
                      f"{' '.join(f'{x:.2f}' for x in r['ratios'])})")
        finally:
            torch.set_num_threads(saved_threads)
    after = other_cpu_use()
    print(f"  other programs' CPU use after: {after}")
    if args.json:
        write_json(args.json, {"target": "busy", "cpus": cpus, "passive_wait": passive_wait(),
                               "seconds": args.seconds, "rounds": args.rounds,
                               "other_cpu_use": {"before": use, "after": after}, "goal": GOAL,
                               "torch": torch.__version__, "loops": rows})
        print(f"  wrote {args.json}")
    return 0
