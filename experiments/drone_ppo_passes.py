"""What fewer PPO passes would buy in drone training time (a question for a decision, not a recipe).

Usage (from the repository root)::

    python -m experiments.drone_ppo_passes --scenario drone-20 [--worlds 16] [--iterations 1] [--threads 1]

Drone training's time is spread over many small ops (research log, "Drone training throughput:
where an iteration goes"), so making each op faster does not reach a 1.5x speed-up; doing fewer
of them does, but changes the recipe and so the trained numbers. This measures, in one process
and on the same machine load, env steps/s of MASP's motor-level drone training (``bench train``'s
recipe) with the shipped PPO passes and with fewer: the Goal Matcher's epochs halved, one
minibatch per epoch instead of two (and four), and both levels' epochs cut. Timing only: nothing is
trained to the end or evaluated, so it says what a recipe change would cost, not what it would
do to SR.
"""
from __future__ import annotations

import argparse
import json

import torch

from masp_lite.bench.train import DRONE_METHODS, throughput

VARIANTS = {
    "shipped": {},
    "gm_ppo_epochs=5": {"gm_ppo_epochs": 5},
    "num_minibatches=1": {"num_minibatches": 1},
    "num_minibatches=4": {"num_minibatches": 4},
    "gm_ppo_epochs=5, ppo_epochs=3": {"gm_ppo_epochs": 5, "ppo_epochs": 3},
}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="drone-20")
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--iterations", type=int, default=1)
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args(argv)
    torch.set_num_threads(args.threads)
    base = None
    for name, extra in VARIANTS.items():
        rate = throughput(args.scenario, {**DRONE_METHODS["masp"], **extra}, args.worlds, args.iterations)
        base = base or rate
        print(json.dumps({"scenario": args.scenario, "variant": name, "env_steps_per_s": round(rate, 1),
                          "x_shipped": round(rate / base, 2)}), flush=True)


if __name__ == "__main__":
    main()
