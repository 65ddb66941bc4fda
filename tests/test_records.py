"""Every committed evaluation record re-evaluates to the same SR, Steps and CR.

A record (``results/**/*.json`` with ``method``, ``scenario``, ``seeds``...) is the output
of ``evaluate --json``; running :func:`masp_lite.evaluation.evaluate` again with its
method, scenario, seeds, episodes, overrides and options must give the same numbers,
exactly (decision time is wall-clock and is not compared). A record made with a weights
file names it and its SHA-256; the file must still be there, unchanged.

Re-evaluating the slow planners on mpe-50 takes minutes each, so by default only the
records whose estimated cost (decision time x steps) is under ``BUDGET_S`` run here;
``MASP_LITE_ALL_RECORDS=1`` runs every one of them (about half an hour on one core).
"""
import json
import os
from pathlib import Path

import pytest

from masp_lite.envs import get_scenario
from masp_lite.evaluation import evaluate
from masp_lite.weights import sha256

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = 30.0


def _records():
    out = []
    for path in sorted((ROOT / "results").rglob("*.json")):
        rec = json.loads(path.read_text())
        if isinstance(rec, dict) and {"method", "scenario", "seeds", "sr"} <= set(rec):
            out.append((path, rec))
    return out


RECORDS = _records()


def _cost_s(rec) -> float:
    sc = get_scenario(rec["scenario"], **rec.get("overrides", {}))
    return rec["decision_ms"]["mean"] / 1e3 * rec["episodes_per_seed"] * len(rec["seeds"]) * sc.horizon


def test_the_records_are_found():
    assert len(RECORDS) >= 30
    assert {r["method"] for _, r in RECORDS} >= {"masp", "h-greedy", "h-orca", "h-rrtstar", "h-voronoi"}


@pytest.mark.slow
@pytest.mark.parametrize("path,rec", RECORDS, ids=[str(p.relative_to(ROOT / "results")) for p, _ in RECORDS])
def test_record_re_evaluates_identically(path, rec, monkeypatch):
    if os.environ.get("MASP_LITE_ALL_RECORDS") != "1" and _cost_s(rec) > BUDGET_S:
        pytest.skip(f"estimated {_cost_s(rec):.0f} s > {BUDGET_S:g} s; MASP_LITE_ALL_RECORDS=1 runs it")
    options = dict(rec.get("method_options", {}))
    if "checkpoint" in options:
        assert sha256(ROOT / options["checkpoint"]) == rec["checkpoint_sha256"], "the weights file changed"
        monkeypatch.chdir(ROOT)  # checkpoint paths are relative to the repository root
    again = evaluate(rec["method"], rec["scenario"], episodes=rec["episodes_per_seed"], seeds=rec["seeds"],
                     overrides=rec.get("overrides"), method_options=options)
    for key in ("sr", "steps", "cr"):
        assert again[key] == rec[key], f"{key}: {again[key]} now, {rec[key]} in {path.name}"
