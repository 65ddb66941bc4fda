"""Does training the Goal Matcher with the evaluation's own decoding, perturbed, close its gap at N = 50?

Usage (from the repository root)::

    python -m experiments.mpe50_joint_draw --seed 0 --out runs/exp-mpe50-joint-s0 [--updates 400] [--resume]
        [--draw perturbed|sequential]

The Goal Matcher is evaluated by the conflict-free joint decoding (the distinct goals that
maximise the summed log-scores, :func:`masp_lite.nets.decoding.joint_argmax`) but trained on
the sequential draw (agents in a random order, each from the goals left): at N = 50 the two
disagree on most agents' first goals (research log, "mpe-50: which level holds MASP back").
``--draw perturbed`` trains on *perturb-and-MAP* samples instead: every score gets an
independent Gumbel draw and the joint decoding runs on the perturbed scores, so a sample is
the evaluation's decision made noisy and the greedy limit is exactly what is evaluated.
Each agent's PPO log-probability is that of its own unrestricted categorical (the sampled
goal under ``S_intra^k``); the log-partition term this leaves out multiplies the mean
advantage, which the normalised advantages make about zero. ``--draw sequential`` is the
control (the product's draw).

Everything else is seed 1's Goal-Matcher-only recipe at N = 50: from the training seed's
mpe-20 weights, executor frozen, R_GM against the Hungarian assignment on squared distances,
16 worlds, lr 7e-4, 10 Goal Matcher epochs, entropy 0.005, a validation row (evaluation seed
12345 x 50) every 10 iterations. The draw is not stored in the run, so resume with the same
``--draw``.
"""
from __future__ import annotations

import argparse

import torch

from experiments import print_validation
from masp_lite.algos.masp_trainer import MASPTrainer
from masp_lite.nets.decoding import joint_argmax
from masp_lite.training import method_config, train

SEED0 = "masp_lite/weights/mpe-20.pt"  # training seed 0's mpe-20 weights are the shipped ones
SETTINGS = ["train_executor=false", "gm_reference=squared", "num_envs=16", "lr=7e-4", "gm_ppo_epochs=10",
            "eval_every=10", "eval_episodes=50", "checkpoint_every=5", "entropy_coef=0.005"]


def perturbed_joint_sample(logits: torch.Tensor, alive: torch.Tensor, generator: torch.Generator,
                           goal_mask: torch.Tensor | None = None):
    """Perturb-and-MAP goals ``(goals, logp, rank)`` in :func:`~masp_lite.nets.goal_draw.sequential_sample`'s form.

    ``rank`` is all zeros: no agent comes before another, so the update's restricted
    categorical is each agent's own, unrestricted one.
    """
    u = torch.rand(logits.shape, generator=generator).clamp(1e-10, 1.0)
    goals = joint_argmax(logits - torch.log(-torch.log(u)), alive, goal_mask)
    logp = torch.gather(torch.log_softmax(logits, -1), -1, goals.unsqueeze(-1)).squeeze(-1)
    return goals, logp, torch.zeros_like(goals)


class PerturbedDrawTrainer(MASPTrainer):
    """MASP's trainer with the Goal Matcher trained on :func:`perturbed_joint_sample`."""

    draw_goals = staticmethod(perturbed_joint_sample)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.mpe50_joint_draw", description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, required=True, choices=[0, 1, 2], help="training seed")
    p.add_argument("--out", required=True)
    p.add_argument("--draw", choices=["perturbed", "sequential"], default="perturbed")
    p.add_argument("--updates", type=int, default=400)
    p.add_argument("--init", help="weights to start from (default: the seed's mpe-20 weights)")
    p.add_argument("--resume", action="store_true")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    init = args.init or (SEED0 if args.seed == 0 else f"results/training/mpe-20-seed{args.seed}.pt")
    method, cfg, overrides = method_config("masp", SETTINGS + [f"updates={args.updates}"], "mpe-50")
    command = f"python -m experiments.mpe50_joint_draw --seed {args.seed} --draw {args.draw}"
    train("mpe-50", cfg, args.out, seed=args.seed, resume=args.resume, init=init, overrides=overrides,
          progress=False, method=method, command=command,
          trainer_type=PerturbedDrawTrainer if args.draw == "perturbed" else None)
    print_validation(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
