"""``python -m masp_lite play --method M --scenario S --out FILE [--seed 0] [--set KEY=VALUE ...] [--goals]``.

Writes one episode as a 2-D ``.gif``/``.mp4`` or a standalone 3-D ``.html`` page
(:func:`masp_lite.viz.play.play`). ``--set`` works as for ``evaluate``: scenario overrides
go to the scenario, other keys to the method (the 3-D export takes scenario overrides only).
``--goals`` (2-D) draws a line from each agent to the goal its method currently pursues.
"""
from __future__ import annotations

from ..evaluation.tables import cell
from ..viz.play import play
from .evaluate import check_writable, split_sets

__all__ = ["add_arguments", "run", "EXAMPLES"]

EXAMPLES = [
    "play --method h-greedy --scenario mpe-20 --out episode.gif      # .gif / .mp4",
    "play --method h-greedy --scenario drone-20 --out drones.html    # standalone 3-D page",
]


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, help="method name (see masp_lite.policies)")
    parser.add_argument("--scenario", required=True, help="scenario preset, e.g. mpe-20")
    parser.add_argument("--out", required=True, help="output file: .gif, .mp4 (2-D) or .html (3-D)")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override or method option (repeatable)")
    parser.add_argument("--goals", action="store_true",
                        help="2-D: draw a line from each agent to its current goal (methods that expose goals)")


def run(args) -> int:
    overrides, options = split_sets(args.set, args.method)
    check_writable(args.out, "--out", "episode.gif")  # before the episode is recorded, not after
    path, result = play(args.method, args.scenario, args.out, seed=args.seed, overrides=overrides,
                        method_options=options, goals=args.goals)
    steps = "\\ (never solved)" if result["steps"] is None else f"{result['steps']:.0f}"
    print(f"{args.method} on {args.scenario}, episode seed {args.seed}: SR {cell((result['sr'], 0.0)).split()[0]}  "
          f"Steps {steps}  CR {result['cr']:.2f}")
    print(f"wrote {path}")
    return 0
