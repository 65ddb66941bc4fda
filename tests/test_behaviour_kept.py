"""Refactoring keeps what training computes: two tiny iterations of each method end at the same weights.

The digests were recorded on the code before the paper-path clean-up (issue 52): ``sha256`` over every
tensor of the trained networks (sorted by name) after two iterations of a tiny run (two worlds, horizon
9, width 8, one PPO epoch), seed 3, one torch thread. A change that moves code without changing what it
computes keeps them; one that changes a sum's order, a random draw or a default does not.
"""
import hashlib

import pytest
import torch

from masp_lite.training import method_config, train

TINY = ["num_envs=2", "eval_every=0", "eval_episodes=2", "width=8", "ppo_epochs=1", "gm_ppo_epochs=1",
        "checkpoint_every=1", "horizon=9", "updates=2"]
DIGESTS = {
    ("masp", "mpe-5"):
        "d59af6c90474d2d574d880b25764fb3f965d04e22f984a5fdb303e962492aacb",
    ("masp", "drone-5"):
        "1ef9172a9de8c5498ae841f6df86bc18355506e5bb89f0aece2df5c2b28fd13c",
    ("masp-velocity", "drone-5"):
        "40a3d5e815ad2ef3cb73043bba12f59ce3234492f665a5ec88c4d4353cfabbe8",
    ("mage-x", "mpe-5"):
        "2c6f4e5d050566f3ec23c0a07208e5b5f2e1ea9a6c994544f45ec723815e740e",
    ("mage-x", "drone-5"):
        "ec17253f86f549ef820b5083c143a0de57fb5f37e986f8b1dfe1774f288c4baa",
    ("mappo", "mpe-5"):
        "c953e4b9f79d0694b84825146b6bdf639384856d6c2b862af464fdd81c2a8076",
    ("mappo", "drone-5"):
        "bb41b549b8451988273c1b13e5b4bea4317c039bed4a8fdf246731e052d53349",
}


def trained_digest(method: str, scenario: str, out) -> str:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # a float sum's rounding depends on the thread count
    try:
        method, cfg, overrides = method_config(method, TINY, scenario)
        train(scenario, cfg, out, seed=3, overrides=overrides, progress=False, method=method)
    finally:
        torch.set_num_threads(threads)
    nets = torch.load(out / "state.pt", weights_only=True)["nets"]
    return hashlib.sha256(b"".join(nets[k].numpy().tobytes() for k in sorted(nets))).hexdigest()


@pytest.mark.parametrize("method,scenario", sorted(DIGESTS))
def test_two_iterations_end_at_the_recorded_weights(method, scenario, tmp_path):
    assert trained_digest(method, scenario, tmp_path / "run") == DIGESTS[method, scenario]
