"""How far drone training's PPO updates are from their arithmetic (a bound for issue 40's option (c)).

Usage (from the repository root)::

    python -m experiments.drone_update_bound --scenario drone-20 [--worlds 16] [--threads 1]

Option (c) of the drone speed-up decision is a hand-written, fused update of both levels. What it
could buy at most is bounded by the matrix products the update must compute. This collects one
rollout of MASP's motor-level drone training (``bench train``'s recipe), then, for each level:

* the matrix-product FLOPs of one minibatch's forward and backward as the product runs them (the
  chunked kernels included, with their recomputation), counted by ``torch.utils.flop_counter``;
* their time, hence the achieved GFLOP/s, beside a bare ``(rows, 32) @ (32, 32)`` product of the
  same rows measured in the same process (what one core does on these shapes at best);
* one pass over the rollout's rows cut into 1 to 32 minibatches: if smaller minibatches that fit the
  CPU cache were much faster per row, chunking (as the fusion kernel does) would pay.
"""
from __future__ import annotations

import argparse
import json
import time

import torch
from torch.utils.flop_counter import FlopCounterMode

from masp_lite.algos.drone_trainer import DroneMASPTrainer
from masp_lite.algos.mappo import RolloutStorage
from masp_lite.bench.train import DRONE_METHODS
from masp_lite.config import TrainConfig
from masp_lite.recipes import FROM_SCRATCH


def _pass(evaluate, minibatches) -> float:
    """Seconds for the forward and backward of every minibatch (best of two)."""
    best = float("inf")
    for _ in range(2):
        t = time.perf_counter()
        for mb in minibatches:
            out, values = evaluate(mb)
            (out[0] if isinstance(out, tuple) else out).sum().add(values.sum()).backward()
        best = min(best, time.perf_counter() - t)
    return best


def bare_rate(rows: int, width: int = 32) -> float:
    """GFLOP/s of one ``(rows, width) @ (width, width)`` product on this core (best of 20)."""
    x, w = torch.randn(rows, width), torch.randn(width, width)
    best = float("inf")
    for _ in range(20):
        t = time.perf_counter()
        x @ w
        best = min(best, time.perf_counter() - t)
    return 2 * rows * width * width / best / 1e9


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="drone-20")
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args(argv)
    torch.set_num_threads(args.threads)
    cfg = TrainConfig.from_flat({**FROM_SCRATCH, **DRONE_METHODS["masp"], "num_envs": args.worlds})
    trainer = DroneMASPTrainer(args.scenario, cfg, seed=0)
    gm_data, cae_data, _ = trainer.collect()
    n = trainer.world.num_agents
    levels = (("goal matcher", gm_data, trainer.gm_evaluate), ("executor", cae_data, trainer.cae_evaluate))
    for level, data, evaluate in levels:
        data = {k: v for k, v in data.items() if k != "reward_mean"}
        rows = data["mask"].shape[0] * data["mask"].shape[1]
        mb = next(RolloutStorage.minibatches(data, cfg.ppo.num_minibatches, torch.Generator().manual_seed(0)))
        with FlopCounterMode(display=False) as counter:
            _pass(evaluate, [mb])
        flops = counter.get_total_flops() / 2  # _pass ran it twice
        seconds = _pass(evaluate, [mb])
        cut = {k: list(RolloutStorage.minibatches(data, k, torch.Generator().manual_seed(0)))
               for k in (1, 2, 4, 8, 16, 32)}
        passes = {k: round(_pass(evaluate, mbs), 3) for k, mbs in cut.items()}
        print(json.dumps({"scenario": args.scenario, "level": level, "minibatch_rows": rows // cfg.ppo.num_minibatches,
                          "gflop": round(flops / 1e9, 2), "seconds": round(seconds, 3),
                          "gflop_per_s": round(flops / seconds / 1e9, 1),
                          "bare_product_gflop_per_s": round(bare_rate(rows // cfg.ppo.num_minibatches * n), 1),
                          "pass_s_by_minibatches": passes}), flush=True)
        trainer.nets.zero_grad()


if __name__ == "__main__":
    main()
