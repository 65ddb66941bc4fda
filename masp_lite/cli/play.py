"""``python -m masp_lite play --method M --scenario S --out FILE [--seed 0] [--set KEY=VALUE ...]``.

Writes one episode as a 2-D ``.gif``/``.mp4`` or a standalone 3-D ``.html`` page
(:func:`masp_lite.viz.play.play`). ``--set`` works as for ``evaluate``: scenario overrides
go to the scenario, other keys to the method (the 3-D export takes scenario overrides only).
"""
from __future__ import annotations

from ..viz.play import play
from .evaluate import split_sets

__all__ = ["add_arguments", "run"]


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, help="method name (see masp_lite.policies)")
    parser.add_argument("--scenario", required=True, help="scenario preset, e.g. mpe-20")
    parser.add_argument("--out", required=True, help="output file: .gif, .mp4 (2-D) or .html (3-D)")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override or method option (repeatable)")


def run(args) -> int:
    overrides, options = split_sets(args.set, args.method)
    path = play(args.method, args.scenario, args.out, seed=args.seed, overrides=overrides,
                method_options=options)
    print(f"wrote {path}")
    return 0
