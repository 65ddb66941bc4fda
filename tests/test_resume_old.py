"""A training state saved before the compact core (issue 37) resumes after it to the same weights.

``tests/data/before-issue-37/{mpe,drone}/`` hold the ``state.pt`` and ``progress.csv`` of tiny
``masp`` runs (mpe-5 and drone-5, horizon 9, width 8, seed 1) stopped after 2 of 4 iterations,
made with the code before the change; the hashes are those of the weights the same code reached
running all 4 iterations without a stop.
"""
import hashlib
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from masp_lite.training import method_config, train
from masp_lite.viz.progress import read_progress

DATA = Path(__file__).resolve().parent / "data" / "before-issue-37"
TINY = ["num_envs=2", "eval_every=0", "eval_episodes=2", "width=8", "ppo_epochs=1", "gm_ppo_epochs=1",
        "checkpoint_every=1", "horizon=9", "updates=4"]
WHOLE = {"mpe": ("mpe-5", "bb4b02bdadedc09ebf34f75c5ecc6f51ca34961e5648a83331f388f9de775a5d"),
         "drone": ("drone-5", "954b6f711cd58dd83185b3ef6df27996c61e3bde2c3c4dc321c1c113aee8b7e9")}


@pytest.mark.parametrize("kind", sorted(WHOLE))
def test_a_state_from_before_resumes_to_the_uninterrupted_weights(kind, tmp_path):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as the states were made (a float sum's rounding depends on it)
    try:
        _resume(kind, tmp_path)
    finally:
        torch.set_num_threads(threads)


def _resume(kind, tmp_path):
    scenario, digest = WHOLE[kind]
    out = tmp_path / "run"
    shutil.copytree(DATA / kind, out)
    method, cfg, overrides = method_config("masp", TINY, scenario)
    train(scenario, cfg, out, seed=1, resume=True, overrides=overrides, progress=False, method=method)
    nets = torch.load(out / "state.pt", weights_only=True)["nets"]
    got = hashlib.sha256(b"".join(nets[k].numpy().tobytes() for k in sorted(nets))).hexdigest()
    assert got == digest
    cols = read_progress(out / "progress.csv")  # the old rows have no PPO health; the new ones have it
    for key in ("gm_approx_kl", "cae_clip_fraction", "cae_explained_variance"):
        assert np.isnan(cols[key][:2]).all() and np.isfinite(cols[key][2:]).all(), key
