"""``python -m masp_lite bench [TARGET] [options]``: run one benchmark target, or all of them."""
from __future__ import annotations

import argparse

from ..bench import TARGETS, load_target

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", nargs="?", default=None,
                        help=f"what to measure, one of {list(TARGETS)} (default: every available one)")
    parser.add_argument("options", nargs=argparse.REMAINDER,
                        help="the target's own options (see: bench TARGET --help)")


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
