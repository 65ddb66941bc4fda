"""Same recipe, same seed, same numbers: the shipped MASP's first stage, re-run for two iterations with
today's code, gives the first rows of its kept history (``results/training/mpe-20-seed0``), every column
but the wall-clock (issue 50)."""
import csv
import json
from pathlib import Path

import torch

from masp_lite.recipes import get_recipe
from masp_lite.training import method_config, train

HISTORY = Path(__file__).resolve().parents[1] / "results" / "training" / "mpe-20-seed0.manifest.json"


def _rows(path, n):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))[:n]


def test_the_first_rows_of_the_shipped_mpe20_history_are_made_again(tmp_path):
    history = json.loads(HISTORY.read_text())
    recipe = get_recipe("masp")
    first = recipe.chain("mpe-20-both")[0]
    kept = history["stages"][0]
    assert kept["scenario"] == first.scenario and kept["training"]["seed"] == 0 and kept["training"]["init"] is None
    assert kept["training"]["config"]["updates"] == first.iterations  # the kept run is this stage, from random networks
    method, cfg, overrides = method_config(recipe.method, [*first.sets(), "updates=2"], first.scenario)
    threads = torch.get_num_threads()
    torch.set_num_threads(kept["training"]["machine"]["torch_threads"])  # as it was trained
    try:
        train(first.scenario, cfg, tmp_path / "run", seed=0, overrides=overrides, progress=False, method=method)
    finally:
        torch.set_num_threads(threads)
    want = _rows(HISTORY.parent / kept["progress"], 2)
    got = _rows(tmp_path / "run" / "progress.csv", 2)
    assert len(want) == len(got) == 2
    for w, g in zip(want, got):
        assert {c: g.get(c) for c in w if c != "wall_s"} == {c: v for c, v in w.items() if c != "wall_s"}
