"""``python -m masp_lite bench [TARGET] [options]``: run one benchmark target, or all of them."""
from __future__ import annotations

import argparse

from ..bench import TARGETS, load_target
from . import epilog, program
from .evaluate import check_writable

__all__ = ["add_arguments", "run", "EXAMPLES", "TARGET_EXAMPLES"]

EXAMPLES = [
    "bench                                  # every target with its defaults",
    "bench env --worlds 64                  # one target, with its options",
    "bench train --help                     # a target's options",
]
#: target -> examples shown at the end of ``bench TARGET --help``
TARGET_EXAMPLES = {
    "env": ["bench env", "bench env --worlds 64 --seconds 4 --json env.json"],
    "decide": ["bench decide", "bench decide --agents 100"],
    "planners": ["bench planners", "bench planners --scenario mpe-20 --methods h-orca h-rrtstar"],
    "drones": ["bench drones", "bench drones --worlds 16 --threads 2"],
    "train": ["bench train", "bench train --scenarios mpe-50 --methods masp --iterations 2"],
    "busy": ["bench busy", "bench busy --loops world decide --rounds 7", "bench busy --threads 2   # every loop at 2"],
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", nargs="?", default=None,
                        help=f"what to measure, one of {list(TARGETS)} (default: every available one)")
    parser.add_argument("options", nargs=argparse.REMAINDER,
                        help="the target's own options (see: bench TARGET --help)")


def _target_args(module, name: str, argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"{program()} bench {name}",
                                     description=TARGETS[name], epilog=epilog(TARGET_EXAMPLES.get(name, ())),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    if hasattr(module, "add_arguments"):
        module.add_arguments(parser)
    args = parser.parse_args(argv)
    if getattr(args, "json", None) is not None:  # a bad path fails now, not after the measurement
        check_writable(args.json)
    return args


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
