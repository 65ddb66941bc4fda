"""Does pricing close passes at speed teach drone-20's executor to give way?

Usage (from the repository root)::

    python -m experiments.drone_nearmiss --coef 0.5 --out runs/exp-drone-near05 [--updates 60]

The research log found that drone-20's crashes are drones crossing hovering ones at 3-3.7 m/s,
and that neither more PPO on R_CAE nor a longer view changed that: nothing in R_CAE prices a
close pass until the contact itself. This fine-tunes the shipped drone-20 executor as the log's
"attempt 2" did (Hungarian goals, executor only, collision coefficient 2, learning rate 3e-4,
16 worlds) with one term added to every alive drone's reward::

    R_near^i = -coef * sum_j  [d_ij < D] * (1 - (d_ij - d_c) / (D - d_c)) * min(1, closing_ij / V)

where d_c = 2 * COLLISION_RADIUS is the contact distance, D = ``--zone`` metres, closing_ij the
speed at which i and j approach each other (0 when they separate) and V = 3 m/s. Both drones of
a pair pay it, so the crossing one learns to slow or swerve and the hovering one to step aside.
``--coef 0`` is the control. It prints the validation rows of ``progress.csv`` (deterministic
policy, 16 episodes, evaluation seed 12345); the weights keep the product's layout.
"""
from __future__ import annotations

import argparse

import torch

from experiments import print_validation
from masp_lite.algos.drone_trainer import DroneMASPTrainer
from masp_lite.envs.drone_model import COLLISION_RADIUS
from masp_lite.training import method_config, train

SHIPPED = "masp_lite/weights/drone-20.pt"
SETTINGS = ["goal_matcher=hungarian", "num_envs=16", "eval_every=10", "eval_episodes=16", "checkpoint_every=5",
            "collision_coef=2", "lr=3e-4"]


def near_miss(pos: torch.Tensor, vel: torch.Tensor, alive: torch.Tensor, zone: float, v_ref: float = 3.0):
    """(B, N) penalty weights (before ``-coef``) of the module docstring's R_near."""
    rel = pos.unsqueeze(1) - pos.unsqueeze(2)                  # (B, i, j, 3): p_j - p_i
    d = rel.norm(dim=-1).clamp_min(1e-6)
    closing = (-(rel * (vel.unsqueeze(1) - vel.unsqueeze(2))).sum(-1) / d).clamp(0.0, v_ref) / v_ref
    d_c = 2 * COLLISION_RADIUS
    near = (1 - (d - d_c) / (zone - d_c)).clamp(0.0, 1.0)
    pair = alive.unsqueeze(1) & alive.unsqueeze(2)
    pair &= ~torch.eye(pos.shape[1], dtype=torch.bool).unsqueeze(0)
    return torch.where(pair, near * closing, torch.zeros_like(d)).sum(-1)


def near_miss_trainer(coef: float, zone: float) -> type[DroneMASPTrainer]:
    """The drone trainer whose R_CAE (crash charge included) also pays ``coef`` times :func:`near_miss`."""

    class NearMissTrainer(DroneMASPTrainer):
        def executor_reward(self, obs, goals, info, alive, t):
            r = super().executor_reward(obs, goals, info, alive, t)
            pen = near_miss(obs["agent_pos"], obs["agent_vel"], alive & obs["alive"], zone)
            return r - coef * torch.where(alive, pen, torch.zeros_like(pen))
    return NearMissTrainer


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_nearmiss", description=__doc__.split("\n")[0])
    p.add_argument("--coef", type=float, required=True, help="weight of the near-miss term")
    p.add_argument("--zone", type=float, default=1.0, help="distance at which a pass starts to cost, metres")
    p.add_argument("--out", required=True)
    p.add_argument("--updates", type=int, default=60)
    p.add_argument("--resume", action="store_true")
    args = p.parse_args(argv)
    if not args.coef >= 0 or not args.zone > 2 * COLLISION_RADIUS:
        raise SystemExit(f"expected --coef >= 0 and --zone > {2 * COLLISION_RADIUS:.2f} m")
    torch.set_num_threads(1)

    method, cfg, overrides = method_config("masp", SETTINGS + [f"updates={args.updates}"], "drone-20")
    train("drone-20", cfg, args.out, seed=0, resume=args.resume, init=SHIPPED, overrides=overrides,
          progress=False, method=method, trainer_type=near_miss_trainer(args.coef, args.zone),
          command=f"python -m experiments.drone_nearmiss --coef {args.coef} --zone {args.zone}")
    print_validation(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
