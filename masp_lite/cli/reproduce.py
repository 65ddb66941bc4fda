"""``python -m masp_lite reproduce [--table NAME] [--format F] [--evaluate | --quick | --train] [--records DIR]``.

Prints the paper's tables with ours beside the paper's (:mod:`masp_lite.reproduction.reproduce`),
then the paper's claims checked on the same records (``--table claims``, ``drone-claims``,
``ablation-claims``): from the records in ``results/`` (seconds), or ``--evaluate`` — every
registered method of the table with its shipped weights, 3 seeds × 100 episodes (about 30
minutes for "mpe" on one core, most of it the planners on mpe-50) — or ``--quick``, 3 seeds ×
4 episodes (60 s for "mpe" on one core, 6.6 min for every table), for a first look and for tests. An
evaluation that several tables read runs once.

``--train`` retrains every kept training run from random networks (:mod:`masp_lite.reproduction.plan`:
the plan is built from the recipes, :mod:`masp_lite.recipes`; ``--dry-run`` prints it with each
run's env steps and, from its kept history, wall-clock here), ships the weights and re-makes the
records made from them in place, then prints the tables. Run it again after a stop: finished stages are skipped, a
stopped one resumes from its last checkpoint. With Ray installed the runs go out as Ray
tasks (a local Ray on this machine's cores, or ``--address`` of a cluster); ``--in-turn``
runs them one after the other. ``--only TEXT`` keeps the runs whose name contains TEXT.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from ..reproduction import REPO_ROOT, RESULTS_DIR
from ..reproduction.plan import describe, load_plan, read_plan, run_plan
from ..reproduction.reproduce import TABLES, build, evaluate_records, load_records, render, text_legend

__all__ = ["add_arguments", "run", "EXAMPLES"]

EXAMPLES = [
    "reproduce                                   # every table, from the records in results/",
    "reproduce --table mpe --format latex",
    "reproduce --table mpe --quick               # evaluate now, 3 seeds x 4 episodes",
    "reproduce --train --dry-run                 # the plan of retraining everything, with its wall-clock",
    "reproduce --train --only mappo/ --in-turn   # retrain the MAPPO runs, one after the other",
]

def add_arguments(parser) -> None:
    parser.add_argument("--table", choices=list(TABLES), action="append", default=None,
                        help="a table to print (repeatable; default: every table)")
    parser.add_argument("--format", default=None, choices=["markdown", "text", "latex"],
                        help="text (at most 100 columns; the default in a terminal), markdown (the default when "
                             "the output is a file or a pipe) or latex")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--evaluate", action="store_true", help="evaluate the methods now, 3 seeds x 100 episodes")
    mode.add_argument("--quick", action="store_true", help="evaluate the methods now, 3 seeds x 4 episodes")
    mode.add_argument("--train", action="store_true", help="retrain every kept run from scratch, re-make its "
                      "records, then print the tables (resumable: run it again after a stop)")
    parser.add_argument("--records", default=None, help=f"folder of evaluate records (default {RESULTS_DIR})")
    train = parser.add_argument_group("--train")
    train.add_argument("--dry-run", action="store_true", help="print the plan and stop")
    train.add_argument("--only", action="append", default=None, metavar="TEXT",
                       help="keep the runs whose name contains TEXT (repeatable), e.g. mappo/ or seed0")
    train.add_argument("--plan", default=None, help="a plan file (JSON, as masp_lite.reproduction.plan.save_plan "
                       "writes) instead of the recipes' plan")
    train.add_argument("--root", default=None, help="the checkout whose runs/, results/ and weights the plan "
                       f"writes (default {REPO_ROOT})")
    train.add_argument("--in-turn", action="store_true", help="run the runs one after the other, without Ray")
    train.add_argument("--address", default=None, help="a running Ray cluster (default: a local Ray on this "
                       "machine's cores)")


def _train(args) -> int:
    if args.in_turn and args.address:
        raise ValueError("--in-turn and --address: expected one of them (in turn here, or on a Ray cluster)")
    root = Path(args.root) if args.root else REPO_ROOT
    runs, skipped = (load_plan(args.plan), []) if args.plan else read_plan(root)
    if args.only:
        runs = [r for r in runs if any(t in r.name for t in args.only)]
        skipped = [(n, why) for n, why in skipped if any(t in n for t in args.only)]
        if not runs:
            raise ValueError(f"--only {args.only}: no run of the plan matches")
    print(describe(runs, skipped, workers=1 if args.in_turn else os.cpu_count() or 1))
    if args.dry_run:
        return 0
    try:
        done = run_plan(runs, root, use_ray=True if args.address else False if args.in_turn else None,
                        address=args.address)
    except KeyboardInterrupt:  # every stage keeps its last checkpoint: the same command goes on from there
        print("\ninterrupted; run the same command again to resume (finished runs are skipped, the others go on "
              "from their last checkpoint)", file=sys.stderr)
        return 130
    print(f"{len(done)} run(s) trained, shipped and evaluated in {root}")
    return 0


def run(args) -> int:
    if args.train:
        status = _train(args)
        if status or args.dry_run or args.plan:
            return status
        args.records = str((Path(args.root) if args.root else REPO_ROOT) / RESULTS_DIR.relative_to(REPO_ROOT))
    elif args.dry_run or args.only or args.plan or args.root or args.in_turn or args.address:
        raise ValueError("--dry-run, --only, --plan, --root, --in-turn and --address go with --train")
    names = args.table or list(TABLES)
    if args.evaluate or args.quick:  # each distinct evaluation once, however many tables read it
        records = evaluate_records(names, episodes=4 if args.quick else 100, progress=True)
    else:
        records = load_records(args.records or RESULTS_DIR)
        if not records:  # every cell would read "—": say so instead of printing empty tables
            raise ValueError(f"--records {args.records or RESULTS_DIR}: found no evaluate records (*.json) there; "
                             "expected a folder such as results/, or --evaluate / --quick to make them")
    fmt = args.format or ("text" if sys.stdout.isatty() else "markdown")
    for name in names:
        print(render(build(name, records, latex=fmt == "latex"), fmt))
        print()
    if fmt == "text":
        print("\n".join(text_legend()))
    return 0
