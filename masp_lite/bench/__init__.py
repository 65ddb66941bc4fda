"""``python -m masp_lite bench [TARGET] [options]``: throughput and latency benchmarks.

Each target is a module ``masp_lite.bench.TARGET`` with ``run(args) -> int`` and, when it
takes options, ``add_arguments(parser)``; this module only dispatches, so the targets stay
independent:

===========  ==============================================================
``env``      particle-world agent-steps/s, and mpe2's in the same run
``decide``   decision time of the methods
``planners`` the classical planners' step time
``drones``   MuJoCo drone world throughput
===========  ==============================================================

Without a target, every target present in this version runs with its defaults.
``python -m masp_lite bench TARGET --help`` lists a target's options.
"""
from __future__ import annotations

import argparse
import importlib
import time

__all__ = ["TARGETS", "add_arguments", "run", "load_target"]

#: target -> one-line description
TARGETS = {
    "env": "particle-world agent-steps/s vs mpe2",
    "decide": "decision time per step of the methods",
    "planners": "step time of the classical planners",
    "drones": "MuJoCo drone world throughput",
}


def calls_per_second(fn, seconds: float, warmup: int = 3) -> float:
    """Calls of ``fn`` per second of wall time, after ``warmup`` untimed calls (shared by every target)."""
    for _ in range(warmup):
        fn()
    n, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        fn()
        n += 1
    return n / elapsed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", nargs="?", default=None,
                        help=f"what to measure, one of {list(TARGETS)} (default: every available one)")
    parser.add_argument("options", nargs=argparse.REMAINDER,
                        help="the target's own options (see: bench TARGET --help)")


def load_target(name: str):
    """The module of bench target ``name``; a clear ValueError when it is unknown or missing."""
    if name not in TARGETS:
        raise ValueError(f"unknown bench target {name!r}; expected one of {list(TARGETS)}")
    module_name = f"{__name__}.{name}"
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as e:
        if e.name == module_name:
            raise ValueError(f"bench target {name!r} is not available in this version "
                             f"({module_name} is missing); expected one of {list(TARGETS)}") from None
        raise


def _target_args(module, name: str, argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"python -m masp_lite bench {name}",
                                     description=TARGETS[name])
    if hasattr(module, "add_arguments"):
        module.add_arguments(parser)
    return parser.parse_args(argv)


def run(args: argparse.Namespace) -> int:
    options = list(getattr(args, "options", None) or [])
    if args.target is not None:
        module = load_target(args.target)
        return int(module.run(_target_args(module, args.target, options)) or 0)
    if options:
        raise ValueError(f"bench: options {options} need a target; expected one of {list(TARGETS)}")
    status = 0
    for name in TARGETS:
        try:
            module = load_target(name)
        except ValueError as e:
            print(f"(skipped) {e}")
            continue
        status = max(status, int(module.run(_target_args(module, name, [])) or 0))
    return status
