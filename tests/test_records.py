"""Every committed evaluation record re-evaluates to the same SR, Steps and CR.

A record (``results/**/*.json`` with ``method``, ``scenario``, ``seeds``...) is the output
of ``evaluate --json``; running :func:`masp_lite.evaluation.evaluate` again with its
method, scenario, world definition, seeds, episodes, batch size, overrides and options must give the same numbers,
exactly (decision time is wall-clock and is not compared), at the torch thread count the record
names (a record without one, made before records named it, re-evaluates at the test's own count).
A record made with a weights file names it and its SHA-256; the file must still be there, unchanged.

Re-evaluating the slow planners on mpe-50, or 100 and 200 agents, takes minutes each, so by
default only the records whose estimated cost (decision and world time x steps) is under ``BUDGET_S`` run here;
``MASP_LITE_ALL_RECORDS=1`` runs every one of them (the 260 records of the last full pass: 1.6 CPU-hours,
48 minutes split over two cores).
"""
import json
import os
from pathlib import Path

import pytest

from masp_lite.envs import MPE2_WORLD, get_scenario
from masp_lite.files import sha256
from masp_lite.reproduction.reproduce import load_records, re_evaluate, re_evaluation_cost_s

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = 30.0


RECORDS = [(Path(r.pop("path")), r) for r in load_records(ROOT / "results") if not r.get("bench")]


def test_the_records_are_found_and_name_their_world():
    assert len(RECORDS) >= 30
    assert {r["method"] for _, r in RECORDS} >= {"masp", "h-greedy", "h-orca", "h-rrtstar", "h-voronoi"}
    for path, rec in RECORDS:  # the world a record names is the one its scenario and overrides make
        assert rec.get("world") == get_scenario(rec["scenario"], **rec.get("overrides", {})).world, path.name


@pytest.mark.slow
@pytest.mark.parametrize("path,rec", RECORDS, ids=[str(p.relative_to(ROOT / "results")) for p, _ in RECORDS])
def test_record_re_evaluates_identically(path, rec, monkeypatch):
    if os.environ.get("MASP_LITE_ALL_RECORDS") != "1" and re_evaluation_cost_s(rec) > BUDGET_S:
        pytest.skip(f"estimated {re_evaluation_cost_s(rec):.0f} s > {BUDGET_S:g} s; MASP_LITE_ALL_RECORDS=1 runs it")
    options = dict(rec.get("method_options", {}))
    if "checkpoint" in options:
        assert sha256(ROOT / options["checkpoint"]) == rec["checkpoint_sha256"], "the weights file changed"
        monkeypatch.chdir(ROOT)  # checkpoint paths are relative to the repository root
    again = re_evaluate(rec)  # in the world, batch and thread count it was made with
    for key in ("sr", "steps", "cr"):
        assert again[key] == rec[key], f"{key}: {again[key]} now, {rec[key]} in {path.name}"


def _training_manifests():
    return sorted((ROOT / "results" / "training").rglob("*.manifest.json"))


@pytest.mark.parametrize("path", _training_manifests(), ids=lambda p: str(p.relative_to(ROOT / "results")))
def test_training_history_names_its_weights_and_curves(path):
    """Each kept run's weights hash to its manifest (shipped ones in the package) and its curves exist."""
    from masp_lite.weights import HERE, load_weights, read_manifest
    m = json.loads(path.read_text())
    shipped = read_manifest().get(m["scenario"], {})
    shipped_here = shipped.get("history") == str(path.relative_to(ROOT))
    weights = HERE / m["file"] if shipped_here else path.parent / m["file"]
    assert sha256(weights) == m["sha256"]
    nets, rec = load_weights(weights, scenario=m["scenario"])
    assert nets.arch == type(nets)(**m["arch"]).arch and rec["scenario"] == m["scenario"]   # settings added later:
    # a manifest written before them names none and means their defaults
    assert m["stages"] and all((path.parent / s["progress"]).exists() for s in m["stages"])
    assert m["stages"][-1]["training"]["world"] == m["world"] == rec.get("world", MPE2_WORLD)  # where it last trained


def test_every_shipped_file_has_its_history():
    from masp_lite.weights import read_manifest
    for name, entry in read_manifest().items():
        history = json.loads((ROOT / entry["history"]).read_text())
        assert history["sha256"] == entry["sha256"] and len(history["stages"]) == entry["stages"]
        assert sum(s["training"]["env_steps"] for s in history["stages"]) == entry["env_steps"]


def test_every_packaged_method_file_is_its_training_seeds_weights():
    """The package's seed-0 copy of each learned method (``methods/manifest.json``) is the file it says it copies,
    byte for byte, so retraining a method cannot leave the package evaluating the old weights."""
    from masp_lite.weights import METHODS_DIR
    for method, presets in json.loads((METHODS_DIR / "manifest.json").read_text()).items():
        for preset, entry in presets.items():
            packaged = METHODS_DIR / entry["file"]
            assert sha256(packaged) == entry["sha256"], (method, preset)
            assert sha256(ROOT / entry["copy_of"]) == entry["sha256"], f"{method}/{preset}: {entry['copy_of']} changed"
