"""Does a view at the contact scale teach the drone executor to keep a margin? Two more pair features, from scratch.

Usage (from the repository root)::

    python -m experiments.drone_contact train --out runs/exp-contact-d5 [--updates 300] [--resume]
    python -m experiments.drone_contact evaluate --checkpoint runs/exp-contact-d5/weights.pt [--episodes 64]

The drones' crashes are grazes at the 0.54 m contact distance of two collision spheres
(``experiments.drone_crashes``). The executor's pair features describe a neighbour by its
direction, its distance clipped at 2 m and its relative velocity over 4 m/s, all on a scale
where 0.54 m and 1 m differ by a quarter of the range; and the Group Information Fusion
averages a neighbour's embedding with its group's and over every group. Margins, a close-pass
price, a longer view and no entropy did not move SR (research log). This asks whether the
input is what is missing: every pair gets two more features,

* proximity ``p = clamp(1 - (d - 0.54 m) / 1 m, 0, 1)``: 1 at contact, 0 from 1.54 m on;
* ``p`` times the closing speed ``-(Δx · Δv) / d`` over ``DRONE_SPEED`` (positive when closing),

and masp-velocity's first stage is trained from scratch with them (drone-5, Hungarian goals,
executor only, 32 worlds, training seed 0: the shipped recipe's stage 1, 300 iterations).
``evaluate`` flies a checkpoint of this script on validation episodes (evaluation seed 12345)
with the same features (as ``evaluate`` measures: the same worlds, seeds and policy, its networks
built here). Both build :class:`ContactNets`, the product's drone networks in the product's order
whose executor reads the two more features. The control is the shipped recipe's stage-1 executor on
the same episodes: ``python -m masp_lite evaluate --method masp-velocity --scenario drone-5 --checkpoint
runs/vel-d5-s0/weights.pt --seeds 12345 --episodes 64``. The weights are for this question only:
the features are not stored in them.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import torch
from torch import nn

from experiments import print_validation
from masp_lite.algos.drone_trainer import DroneMASPTrainer
from masp_lite.config import NetConfig
from masp_lite.envs import make
from masp_lite.evaluation import MAX_ENVS, collision_rate, reached_target, rollout, steps, success_rate
from masp_lite.nets.drones import DRONE_SPEED, PAIR_FEATURES, DroneExecutor, DroneNets
from masp_lite.nets.fusion import GroupInformationFusion
from masp_lite.policies.drone_masp import DroneMASPPolicy
from masp_lite.training import method_config, train
from masp_lite.weights import read_weights

CONTACT = 0.54   # m: two collision spheres of 0.27 m touch
RANGE = 1.0      # m beyond contact over which proximity falls from 1 to 0
STAGE1 = ["goal_matcher=hungarian", "num_envs=32", "eval_every=10", "eval_episodes=16", "checkpoint_every=5"]
EVAL_SEED = 12345


def contact_features(pos: torch.Tensor, vel: torch.Tensor, max_speed: float) -> torch.Tensor:
    """The two contact-scale pair features (B, N, N, 2): proximity and proximity times the closing speed."""
    rel = pos.unsqueeze(1) - pos.unsqueeze(2)                    # [b, k, j] = x_j - x_k
    d = rel.norm(dim=-1, keepdim=True)
    p = (1 - (d - CONTACT) / RANGE).clamp(0, 1)
    dv = vel.unsqueeze(1) - vel.unsqueeze(2)
    closing = -(rel * dv).sum(-1, keepdim=True) / d.clamp(min=1e-6) / max_speed
    self_pair = torch.eye(pos.shape[1], dtype=torch.bool, device=pos.device).unsqueeze(-1)
    return torch.cat([p, p * closing], dim=-1).masked_fill(self_pair, 0.0)


class ContactNets(DroneNets):
    """The product's drone networks whose executor's pair features (B, N, N, 8) get the two contact-scale
    ones (B, N, N, 10). Built in :class:`DroneNets`' order, the fusion where the executor builds its own, so
    a seed draws the weights of the runs in the research log."""

    def build_executor(self, c: NetConfig, fusion: nn.Module | None, goal_embed: nn.Module | None) -> nn.Module:
        return DroneExecutor(c.width, c.gcn_layers, c.action, c.log_std_init,
                             fusion=GroupInformationFusion(PAIR_FEATURES + 2, c.width, c.gcn_layers))

    def cae_inputs(self, obs: dict, goals: torch.Tensor, perm: torch.Tensor):
        inputs = super().cae_inputs(obs, goals, perm)
        extra = contact_features(obs["agent_pos"], obs["agent_vel"], DRONE_SPEED)
        pair, *rest = inputs  # a NamedTuple: the same fields with the contact features appended to the pair's
        return type(inputs)(torch.cat([pair, extra], dim=-1), *rest)


class ContactTrainer(DroneMASPTrainer):
    nets_class = ContactNets


def contact_evaluate(checkpoint: str, scenario: str, episodes: int) -> dict:
    """``evaluate``'s record (``sr``, ``steps``, ``cr`` as mean and std over the episodes) of a checkpoint of
    this script, flown deterministically on validation episodes (evaluation seed ``EVAL_SEED``)."""
    rec = read_weights(checkpoint)
    nets = ContactNets(**rec["arch"])
    nets.load_state_dict(rec["state_dict"])
    world = make(scenario, num_envs=min(episodes, MAX_ENVS), seed=EVAL_SEED)
    log, _ = rollout(world, DroneMASPPolicy.from_nets(world, nets, seed=EVAL_SEED), episodes, EVAL_SEED)
    stats = {k: {"mean": float(np.mean(x)), "std": float(np.std(x))} for k, x in
             (("sr", success_rate(log).numpy()), ("steps", steps(log).numpy()), ("cr", collision_rate(log).numpy()))}
    if not reached_target(log).any():  # no episode solved: no Steps (the paper's backslash)
        stats["steps"] = {"mean": None, "std": None}
    return {"method": "masp-velocity", "scenario": scenario, "episodes_per_seed": episodes, **stats}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.drone_contact", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="masp-velocity's stage 1 from scratch with the contact features")
    t.add_argument("--out", required=True)
    t.add_argument("--updates", type=int, default=300)
    t.add_argument("--resume", action="store_true")
    e = sub.add_parser("evaluate", help="validation episodes (evaluation seed 12345) with the contact features")
    e.add_argument("--checkpoint", required=True)
    e.add_argument("--scenario", default="drone-5")
    e.add_argument("--episodes", type=int, default=64)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    if args.command == "train":
        method, cfg, overrides = method_config("masp-velocity", STAGE1 + [f"updates={args.updates}"], "drone-5")
        train("drone-5", cfg, args.out, seed=0, resume=args.resume, overrides=overrides, progress=False,
              method=method, trainer_type=ContactTrainer,
              command=" ".join(["python -m experiments.drone_contact", *(sys.argv[1:] if argv is None else argv)]))
        print_validation(args.out)
    else:
        print(json.dumps(contact_evaluate(args.checkpoint, args.scenario, args.episodes)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
