"""``python -m masp_lite reproduce [--table NAME] [--format F] [--evaluate | --quick] [--records DIR]``.

Prints the paper's tables with ours beside the paper's (:mod:`masp_lite.evaluation.reproduce`),
then the paper's claims checked on the same records (``--table claims``, ``drone-claims``,
``ablation-claims``): from the records in ``results/`` (seconds), or ``--evaluate`` — every
registered method of the table with its shipped weights, 3 seeds × 100 episodes (about 30
minutes for "mpe" on one core, most of it the planners on mpe-50) — or ``--quick``, 3 seeds ×
4 episodes (60 s for "mpe" on one core), for a first look and for tests.
"""
from __future__ import annotations

from ..evaluation.reproduce import RESULTS_DIR, TABLES, build, evaluate_records, load_records, render

__all__ = ["add_arguments", "run", "EXAMPLES"]

EXAMPLES = [
    "reproduce                                   # every table, from the records in results/",
    "reproduce --table mpe --format latex",
    "reproduce --table mpe --quick               # evaluate now, 3 seeds x 4 episodes",
]


def add_arguments(parser) -> None:
    parser.add_argument("--table", choices=list(TABLES), action="append", default=None,
                        help="a table to print (repeatable; default: every table)")
    parser.add_argument("--format", default="markdown", choices=["markdown", "text", "latex"])
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--evaluate", action="store_true", help="evaluate the methods now, 3 seeds x 100 episodes")
    mode.add_argument("--quick", action="store_true", help="evaluate the methods now, 3 seeds x 4 episodes")
    parser.add_argument("--records", default=None, help=f"folder of evaluate records (default {RESULTS_DIR})")


def run(args) -> int:
    names = args.table or list(TABLES)
    if args.evaluate or args.quick:  # each table's records once; the claims read them all
        sources = {"claims": ["mpe", "mpe-varying", "per-step-time"],
                   "drone-claims": ["omnidrones", "omnidrones-varying"],
                   "ablation-claims": ["ab", "groupsize", "globalsteps"]}
        needed = dict.fromkeys(t for name in names for t in sources.get(name, [name]))
        records = [r for name in needed
                   for r in evaluate_records(name, episodes=4 if args.quick else 100, progress=True)]
    else:
        records = load_records(args.records or RESULTS_DIR)
    for name in names:
        print(render(build(name, records, latex=args.format == "latex"), args.format))
        print()
    return 0
