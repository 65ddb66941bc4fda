"""Throughput and latency benchmarks (``python -m masp_lite bench [TARGET] [options]``).

Each target is a module ``masp_lite.bench.TARGET`` with ``run(args) -> int`` and, when it
takes options, ``add_arguments(parser)``; :mod:`masp_lite.cli.bench` dispatches to them,
so the targets stay independent. Each prints its measurement beside a reference measured
in the same run (ratios, never absolute timings in tests):

===========  ==============================================================
``env``      particle-world agent-steps/s, and mpe2's in the same run
``decide``   decision time of the methods
``planners`` the classical planners' step time
``drones``   MuJoCo drone world throughput
``train``    training env steps/s per method, and MASP's on plain autograd
``busy``     the hot loops beside a competing busy process: busy / idle ratios
===========  ==============================================================

Without a target, every target present in this version runs with its defaults.
``python -m masp_lite bench TARGET --help`` lists a target's options.
"""
from __future__ import annotations

import importlib
import json
import os
import time

from ..files import atomic_write

__all__ = ["TARGETS", "calls_per_second", "load_target", "load_average", "write_json"]

#: target -> one-line description
TARGETS = {
    "env": "particle-world agent-steps/s vs mpe2",
    "decide": "decision time per step of the methods",
    "planners": "step time of the classical planners",
    "drones": "MuJoCo drone world throughput",
    "train": "training env steps/s per method vs plain autograd",
    "busy": "the hot loops with and without a competing busy process (busy / idle)",
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


def load_average() -> float | None:
    """One-minute load average, rounded to 0.01 (None where the OS does not report it): every
    target prints it, since other work on the machine inflates every timing."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def write_json(path, result: dict, indent: int = 2) -> None:
    """Write a target's numbers to ``path`` (its ``--json`` option), making missing folders."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic_write(path, json.dumps(result, indent=indent) + "\n")


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
