"""Re-make evaluation records in place after a change that moves their numbers (e.g. the Goal Matcher's decoding).

Usage (from the repository root)::

    python -m experiments.remake_records --methods masp gm-mlp [--only mpe-20 ...] [--dry-run] [--budget-s 120]

Every record under ``results/`` whose method is listed is evaluated again exactly as
``tests/test_records.py`` re-evaluates it (:func:`masp_lite.reproduction.reproduce.re_evaluate`:
its world definition, seeds, episodes, batch size, overrides, options, weights file and
thread count) and, when SR, Steps or CR differ, rewritten with the new numbers (the rest of
the record kept). ``--only`` keeps the records of some scenarios;
``--budget-s`` skips records whose estimated cost is higher (as the test's time rule);
``--dry-run`` reports what differs without writing. Prints one line per record: old and new
Steps / SR / CR.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from masp_lite.reproduction.reproduce import load_records, re_evaluate, re_evaluation_cost_s

ROOT = Path(__file__).resolve().parents[1]


def records(methods, only=()):
    """(path, record) of the records of ``methods`` (and of scenarios ``only``, when given), sorted by path."""
    return [(Path(r.pop("path")), r) for r in load_records(ROOT / "results")
            if not r.get("bench") and r["method"] in methods and (not only or r["scenario"] in only)]


def _short(r) -> str:
    steps = "\\" if r["steps"]["mean"] is None else f"{r['steps']['mean']:.2f}"
    return f"{steps} / {r['sr']['mean']:.4f} / {r['cr']['mean']:.4f}"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.remake_records", description=__doc__.split("\n")[0])
    p.add_argument("--methods", nargs="+", required=True)
    p.add_argument("--only", nargs="+", default=[], help="scenarios to keep")
    p.add_argument("--budget-s", type=float, default=None, help="skip records estimated to take longer")
    p.add_argument("--dry-run", action="store_true")
    a = p.parse_args(argv)
    os.chdir(ROOT)  # checkpoint paths in records are relative to the repository root
    for path, rec in records(a.methods, a.only):
        name = path.relative_to(ROOT)
        if a.budget_s is not None and re_evaluation_cost_s(rec) > a.budget_s:
            print(f"{name}: skipped (estimated {re_evaluation_cost_s(rec):.0f} s)", flush=True)
            continue
        new = re_evaluate(rec)
        same = all(new[k] == rec[k] for k in ("sr", "steps", "cr"))
        print(f"{name}: {_short(rec)} -> {_short(new)}{'  (same)' if same else ''}", flush=True)
        if not same and not a.dry_run:
            keep = {k: v for k, v in rec.items() if k not in new}
            path.write_text(json.dumps({**new, **keep}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
