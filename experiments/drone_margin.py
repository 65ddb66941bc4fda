"""Does a safety margin in training stop drone-20's executor from grazing the others?

Usage (from the repository root)::

    python -m experiments.drone_margin --radius 0.32 --out runs/exp-drone-margin32 [--updates 50]
    python -m experiments.drone_margin --radius 0.32 --scenario drone-5 --num-envs 32 --updates 100 \
        --out runs/exp-drone5-margin32

``experiments.drone_crashes`` found that MASP's drones crash by grazing: two drones pass at
exactly the contact distance of their collision spheres (2 x 0.27 m). The planners keep a
margin beyond that distance; MASP's reward only charges the contact. This fine-tunes the
shipped drone-20 executor as the research log's "attempt 2" (Hungarian goals, executor only,
collision coefficient 2, learning rate 3e-4, 16 worlds) in a world whose collision spheres
have radius ``--radius`` (the scenario override ``collision_radius``: a crash in training at
2 x radius, the spawns spaced by it too), so that the executor learns to keep that distance;
the weights are then meant to fly the true world, with its 0.27 m spheres. The periodic
validation rows printed here are in the training world (inflated spheres). The weights name
that world, so flying them in the true world says so (``any_scenario``)::

    python -m masp_lite evaluate --method masp --scenario drone-20 --checkpoint OUT/weights.pt \
        --seeds 12345 --episodes 32 --set any_scenario=true
"""
from __future__ import annotations

import argparse
import sys

import torch

from experiments import print_validation
from masp_lite.envs.drone_model import COLLISION_RADIUS
from masp_lite.training import method_config, train
from masp_lite.weights import default_checkpoint

SETTINGS = ["goal_matcher=hungarian", "eval_every=10", "eval_episodes=16", "checkpoint_every=5",
            "collision_coef=2", "lr=3e-4"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_margin", description=__doc__.split("\n")[0])
    p.add_argument("--radius", type=float, required=True, help="collision sphere radius in training, metres")
    p.add_argument("--out", required=True)
    p.add_argument("--updates", type=int, default=50)
    p.add_argument("--scenario", default="drone-20", choices=["drone-5", "drone-20"])
    p.add_argument("--init", help="weights to start from (default: the shipped ones of --scenario)")
    p.add_argument("--num-envs", type=int, default=16)
    p.add_argument("--resume", action="store_true")
    p.add_argument("--method", default="masp", choices=("masp", "masp-velocity"),
                   help="masp-velocity needs --init (its weights are not shipped)")
    args = p.parse_args(argv)
    if not args.radius >= COLLISION_RADIUS:
        raise SystemExit(f"--radius: expected at least the true {COLLISION_RADIUS:.2f} m, got {args.radius}")
    torch.set_num_threads(1)
    settings = SETTINGS + [f"updates={args.updates}", f"num_envs={args.num_envs}", f"collision_radius={args.radius}"]
    if args.method != "masp" and not args.init:
        raise SystemExit(f"--method {args.method}: pass --init (weights of that method)")
    method, cfg, overrides = method_config(args.method, settings, args.scenario)
    train(args.scenario, cfg, args.out, seed=0, resume=args.resume, init=args.init or default_checkpoint(args.scenario),
          overrides=overrides, progress=False, method=method,
          command=" ".join(["python -m experiments.drone_margin", *(sys.argv[1:] if argv is None else argv)]))
    print_validation(args.out, "SR (inflated spheres)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
