"""``python -m masp_lite bench train``: training throughput in environment steps per second.

One environment step is one step of one world (all its agents), the unit of every training
budget in the manifests. For each scenario (``mpe-20``, ``mpe-50``, ``drone-5`` and ``drone-20`` by default) and each
method — on particle worlds MASP and the RL baselines, :data:`METHODS`; on drone worlds MASP with motor
commands, ``masp-velocity`` and the RL baselines, :data:`DRONE_METHODS` (MuJoCo then steps the worlds with
``mujoco.batch`` on ``--threads`` threads too) — the trainer is built with the from-scratch recipe
(:data:`masp_lite.recipes.FROM_SCRATCH`, ``--worlds`` worlds), one iteration
(an episode in every world, then PPO on both levels) warms up, and ``--iterations``
iterations are timed with ``time.perf_counter``, with ``--threads`` torch threads.

The reference, measured in the same run: MASP with the chunked kernels off
(``use_kernels(trainer.nets, False)``, :func:`masp_lite.nets.kernels.use_kernels`: the Group Information Fusion and the
Cross-Encoder's score head from plain torch ops, differentiated by autograd). The ratio
"x plain" is what the kernels buy; "x masp" compares each method with MASP. On drone
worlds the world's step is a fixed share of every row (MuJoCo's physics about a tenth of
MASP's time at one thread, with the observations 12–13 %), and the networks are small, so
the kernels buy less there than on particle worlds. Other work on
the machine slows every row alike, so the ratios hold better than the absolute figures;
the output prints the load average.
"""
from __future__ import annotations

import time

import torch

from ..config import TrainConfig
from ..envs import get_scenario
from ..nets.kernels import use_kernels
from ..policies import learned_methods
from ..recipes import FROM_SCRATCH
from ..threads import TRAIN_THREADS
from . import load_average, write_json
from .competing import warn_if_busy

__all__ = ["add_arguments", "run", "throughput", "METHODS", "DRONE_METHODS"]

METHODS = {m: {**e["nets"], **e.get("train", {})} for m, e in learned_methods("particle").items()
           if m == "masp" or e.get("group") == "baseline"}
"""Measured methods on particle worlds (MASP and the RL baselines) -> the training settings that make each one."""
DRONE_METHODS = {m: {**e["nets"], **e.get("train", {})} for m, e in learned_methods("drone").items()}
"""Measured methods on drone worlds -> their settings."""


def add_arguments(parser) -> None:
    parser.add_argument("--scenarios", nargs="+", default=["mpe-20", "mpe-50", "drone-5", "drone-20"],
                        help="default: mpe-20 mpe-50 drone-5 drone-20")
    parser.add_argument("--methods", nargs="+", default=None,
                        help=f"default: {' '.join(METHODS)} (particle), {' '.join(DRONE_METHODS)} (drones)")
    parser.add_argument("--worlds", type=int, default=16, help="worlds per iteration (default 16)")
    parser.add_argument("--iterations", type=int, default=1, help="timed iterations per row (default 1)")
    parser.add_argument("--threads", type=int, default=TRAIN_THREADS,
                        help=f"torch threads (default {TRAIN_THREADS}, as train)")
    parser.add_argument("--no-reference", action="store_true", help="skip the plain-autograd MASP row")
    parser.add_argument("--json", default=None, help="also write the numbers to this JSON file")


def throughput(scenario: str, settings: dict, worlds: int = 16, iterations: int = 1, plain: bool = False) -> float:
    """Environment steps per second of training with ``settings`` added to the recipe."""
    from ..algos.drone_trainer import DroneMASPTrainer
    from ..algos.masp_trainer import MASPTrainer
    cfg = TrainConfig.from_flat({**FROM_SCRATCH, **settings, "num_envs": worlds})
    drone = get_scenario(scenario).kind == "drone"
    trainer = (DroneMASPTrainer if drone else MASPTrainer)(scenario, cfg, seed=0)
    use_kernels(trainer.nets, not plain)
    trainer.iteration()  # warm-up
    start, t0 = trainer.env_steps, time.perf_counter()
    for _ in range(iterations):
        trainer.iteration()
    return (trainer.env_steps - start) / (time.perf_counter() - t0)


def run(args) -> int:
    for name in ("worlds", "iterations", "threads"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name}: expected a positive int, got {getattr(args, name)}")
    kinds = {sc: get_scenario(sc).kind for sc in args.scenarios}
    known = {**METHODS, **DRONE_METHODS}
    unknown = [m for m in args.methods or () if m not in known]
    if unknown:
        raise ValueError(f"--methods: unknown {unknown}; expected some of {list(known)}")
    torch.set_num_threads(args.threads)
    load = load_average()
    warn_if_busy()
    print(f"training throughput, env steps/s ({args.worlds} worlds, {args.threads} threads, "
          f"{args.iterations} timed iteration(s) after one warm-up)")
    res = {"worlds": args.worlds, "threads": args.threads, "iterations": args.iterations,
           "load_average_1min": load, "env_steps_per_s": {}}
    for sc in args.scenarios:
        table = DRONE_METHODS if kinds[sc] == "drone" else METHODS
        methods = [m for m in (args.methods or table) if m in table]
        rows = {m: throughput(sc, table[m], args.worlds, args.iterations) for m in methods}
        if not args.no_reference:
            rows["masp (plain autograd)"] = throughput(sc, table["masp"], args.worlds, args.iterations, plain=True)
        res["env_steps_per_s"][sc] = rows
        masp = rows.get("masp")
        plain = rows.get("masp (plain autograd)")
        print(f"{sc}:")
        for name, sps in rows.items():
            extra = [f"x masp {sps / masp:.2f}" if masp and name != "masp" else "",
                     f"x plain {sps / plain:.2f}" if plain and name == "masp" else ""]
            print(f"  {name:<24} {sps:8.1f}   {'  '.join(e for e in extra if e)}")
    print(f"(1-minute load average at start: {load}; other work on the machine slows every row)")
    if args.json:
        write_json(args.json, res)
    return 0
