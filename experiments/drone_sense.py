"""Does seeing farther teach drone-20's executor to give way? The pair features' clip, 2 m -> ``--sense`` m.

Usage (from the repository root)::

    python -m experiments.drone_sense --sense 4 --out runs/exp-drone-sense4 [--updates 60]

Fine-tunes the shipped drone-20 executor as the research log's "attempt 2" did (Hungarian goals,
executor only, collision coefficient 2, learning rate 3e-4, 16 worlds, from the shipped weights),
with one change: the executor's pair features clip relative positions at ``--sense`` metres
instead of ``DroneNets.sense`` (2 m), so that a drone crossing at 3.5 m/s sees another one earlier.
``--sense 2`` is the control. It prints the validation rows of ``progress.csv`` (deterministic
policy, 16 episodes, evaluation seed 12345). The weights keep the product's layout; the clip is
not stored in them, so they are for this question only.
"""
from __future__ import annotations

import argparse

import torch

from experiments import print_validation
from masp_lite.algos.drone_trainer import DroneMASPTrainer
from masp_lite.nets.drones import DroneNets
from masp_lite.training import method_config, train

SHIPPED = "masp_lite/weights/drone-20.pt"
SETTINGS = ["goal_matcher=hungarian", "num_envs=16", "eval_every=10", "eval_episodes=16", "checkpoint_every=5",
            "collision_coef=2", "lr=3e-4"]


def sense_trainer(sense: float) -> type[DroneMASPTrainer]:
    """The drone trainer whose networks clip the pair features at ``sense`` metres (in its evaluations too)."""

    class SenseNets(DroneNets):
        pass
    SenseNets.sense = sense

    class SenseTrainer(DroneMASPTrainer):
        nets_class = SenseNets
    return SenseTrainer


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_sense", description=__doc__.split("\n")[0])
    p.add_argument("--sense", type=float, required=True, help="clip of the relative positions, metres")
    p.add_argument("--out", required=True)
    p.add_argument("--updates", type=int, default=60)
    p.add_argument("--resume", action="store_true")
    args = p.parse_args(argv)
    if not args.sense > 0:
        raise SystemExit(f"--sense: expected a positive number of metres, got {args.sense}")
    torch.set_num_threads(1)
    method, cfg, overrides = method_config("masp", SETTINGS + [f"updates={args.updates}"], "drone-20")
    train("drone-20", cfg, args.out, seed=0, resume=args.resume, init=SHIPPED, overrides=overrides,
          progress=False, method=method, trainer_type=sense_trainer(args.sense),
          command=f"python -m experiments.drone_sense --sense {args.sense}")
    print_validation(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
