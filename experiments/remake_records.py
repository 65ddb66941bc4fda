"""Re-make evaluation records in place after a change that moves their numbers (e.g. the Goal Matcher's decoding).

Usage (from the repository root)::

    python -m experiments.remake_records --methods masp gm-mlp [--only mpe-20 ...] [--dry-run] [--budget-s 120]

Every record under ``results/`` (a JSON file with ``method``, ``scenario``, ``seeds`` and
``sr``) whose method is listed is evaluated again exactly as ``tests/test_records.py``
re-evaluates it — its world definition, seeds, episodes, batch size, overrides, options,
weights file and thread count — and, when SR, Steps or CR differ, rewritten with the new
numbers (the rest of the record kept). ``--only`` keeps the records of some scenarios;
``--budget-s`` skips records whose estimated cost is higher (as the test's time rule);
``--dry-run`` reports what differs without writing. Prints one line per record: old and new
Steps / SR / CR.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import torch

from masp_lite.envs import get_scenario
from masp_lite.evaluation import evaluate

ROOT = Path(__file__).resolve().parents[1]


def records(methods, only=()):
    """(path, record) of the records of ``methods`` (and of scenarios ``only``, when given), sorted by path."""
    out = []
    for path in sorted((ROOT / "results").rglob("*.json")):
        rec = json.loads(path.read_text())
        if isinstance(rec, dict) and {"method", "scenario", "seeds", "sr"} <= set(rec) and rec["method"] in methods \
                and (not only or rec["scenario"] in only):
            out.append((path, rec))
    return out


def cost_s(rec) -> float:
    """Seconds a re-evaluation takes, roughly (decision time and the world's, over every world-step)."""
    sc = get_scenario(rec["scenario"], **rec.get("overrides", {}))
    per_step = rec["decision_ms"]["mean"] / 1e3 + 1e-5 * sc.num_agents
    return per_step * rec["episodes_per_seed"] * len(rec["seeds"]) * sc.horizon


def remake(rec) -> dict:
    """The record evaluated again as it was made; returns the new record (same keys)."""
    options = dict(rec.get("method_options", {}))
    threads = torch.get_num_threads()
    torch.set_num_threads(rec.get("threads", threads))
    try:
        new = evaluate(rec["method"], rec["scenario"], episodes=rec["episodes_per_seed"], seeds=rec["seeds"],
                       overrides={**rec["world"], **rec.get("overrides", {})}, method_options=options,
                       num_envs=rec.get("num_envs"))
    finally:
        torch.set_num_threads(threads)
    if "overrides" not in rec:  # the world definition was passed as overrides only to rebuild it
        new.pop("overrides", None)
    elif new.get("overrides") != rec["overrides"]:
        new["overrides"] = rec["overrides"]
    return new


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
        if a.budget_s is not None and cost_s(rec) > a.budget_s:
            print(f"{name}: skipped (estimated {cost_s(rec):.0f} s)", flush=True)
            continue
        new = remake(rec)
        same = all(new[k] == rec[k] for k in ("sr", "steps", "cr"))
        print(f"{name}: {_short(rec)} -> {_short(new)}{'  (same)' if same else ''}", flush=True)
        if not same and not a.dry_run:
            keep = {k: v for k, v in rec.items() if k not in new}
            path.write_text(json.dumps({**new, **keep}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
