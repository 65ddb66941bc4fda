"""How close does imitation bring the Goal Matcher to the min-max assignment? (``masp-minmax``'s first stage.)

Usage (from the repository root)::

    python -m experiments.minmax_imitation train --scenario mpe-50 --loss sequential --states spawn \\
        --updates 300 --worlds 32 --measure-every 50 --out runs/exp-minmax-seq
    python -m experiments.minmax_imitation measure masp_lite/weights/mpe-20.pt

``train`` runs the product's imitation stage (``train --method masp-minmax --set imitate=h-bottleneck``, from
``--init``, by default the shipped mpe-20 weights; ``--loss decoding``, the product's margin) or the same
stage with a loss tried and not kept (``--loss sequential`` or ``independent``: the likelihood of the
teacher's goals under the training draw, :func:`masp_lite.algos.imitation.draw_nll`; ``--credit within``
counts every goal within the teacher's longest trip as right; a trainer subclass, :class:`Likelihood`) and,
every ``--measure-every`` iterations, measures the Goal Matcher on validation layouts; ``measure`` measures
weights files. On episode starts of evaluation seed ``--seed`` (100+: never a training or record seed),
``--layouts`` of each validation scenario (mpe-20, mpe-50, and mpe-50 with 100 agents, zero-shot), it prints
one JSON line with, per scenario, how often the policy's decoding (the conflict-free squared decoding of
``evaluate``) equals ``h-bottleneck``'s assignment (per layout: ``exact``; per agent: ``agree``), the ratio of
the decoded assignment's longest agent-goal distance to the bottleneck's (``makespan``: mean over layouts;
``within5``: share of layouts within 5 %), and the same ratio for the training draw (``draw``: agents in a
random order, each sampling among the goals left), the goals MAPPO's rollouts fly to.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from masp_lite.algos.imitation import ImitationTrainer, draw_nll, random_rank, within_longest_trip
from masp_lite.algos.team import bottleneck
from masp_lite.envs import make
from masp_lite.nets.decoding import joint_argmax
from masp_lite.nets.goal_draw import sequential_sample
from masp_lite.training import method_config, train
from masp_lite.weights import load_weights, save_weights


class Rollout(ImitationTrainer):
    """The imitation on DAgger's states (tried, not kept): every global step of one episode per world, the
    executor flying to the goals the policy's own decoding picks, so the layouts are those the policy meets
    when it acts (agents moving, on their landmarks, landmarks covered)."""

    @staticmethod
    def draw_goals(logits, alive, generator):
        goals = joint_argmax(logits, alive)
        return goals, torch.zeros(goals.shape), torch.zeros_like(goals)

    def layouts(self):
        gm_data, _, stats = self.collect()
        return {k: gm_data[k].flatten(0, 1) for k in self.obs_keys}, stats


class Likelihood(ImitationTrainer):
    """The imitation stage with the draw's likelihood of the teacher's goals as its loss (not kept)."""

    sequential, credit = True, "teacher"

    def loss(self, logits, obs, targets, goal_mask):
        rank = random_rank(*targets.shape, self.generator) if self.sequential else None
        accept = within_longest_trip(obs, targets, goal_mask) if self.credit == "within" else None
        return draw_nll(logits, targets, obs["alive"], rank, goal_mask, accept)


def trainer_type(loss: str, credit: str, states: str = "spawn"):
    """The trainer of a ``--loss`` and ``--states``: the product's (``None``) for ``decoding`` on episode starts,
    a :class:`Rollout` on DAgger's states, else a :class:`Likelihood`."""
    if loss == "decoding":
        return None if states == "spawn" else Rollout
    if states != "spawn":
        raise SystemExit("--states rollout: with --loss decoding only")
    return type(f"Likelihood_{loss}_{credit}", (Likelihood,), {"sequential": loss == "sequential",
                                                                "credit": credit})


VALIDATION = {"mpe-20": {}, "mpe-50": {}, "mpe-50 N=100": {"num_agents": 100}}
"""Validation scenario -> (preset, overrides) of its layouts."""


def makespan(obs: dict, goals: torch.Tensor) -> torch.Tensor:
    """The longest alive agent-to-goal distance of every layout (B,)."""
    goal_pos = torch.gather(obs["landmark_pos"], 1, goals.clamp(min=0).unsqueeze(-1).expand_as(obs["agent_pos"]))
    d = (obs["agent_pos"] - goal_pos).norm(dim=-1)
    return d.masked_fill(~obs["alive"], 0.0).max(-1).values


def validation_layouts(layouts: int, seed: int) -> dict:
    """Validation scenario -> (its episode starts, map half-side, the bottleneck's goals)."""
    out = {}
    for name, overrides in VALIDATION.items():
        world = make(name.split()[0], num_envs=layouts, seed=seed, **overrides)
        obs = world.reset()
        out[name] = (obs, world.scenario.world_size / 2, bottleneck(obs["agent_pos"], obs["landmark_pos"],
                                                                     obs["alive"]))
    return out


@torch.no_grad()
def measure(nets, layouts: dict) -> dict:
    """Agreement with the bottleneck and makespan ratio of the decoded goals, per validation scenario."""
    rows = {}
    for name, (obs, scale, target) in layouts.items():
        logits = nets.gm_logits(obs, scale)
        goals = joint_argmax(logits, obs["alive"])
        ratio = makespan(obs, goals) / makespan(obs, target)
        drawn = sequential_sample(logits, obs["alive"], torch.Generator().manual_seed(0))[0]
        rows[name] = {"exact": round(float((goals == target).all(-1).float().mean()), 4),
                      "agree": round(float((goals == target).float().mean()), 4),
                      "makespan": round(float(ratio.mean()), 4),
                      "within5": round(float((ratio <= 1.05).float().mean()), 4),
                      "draw": round(float((makespan(obs, drawn) / makespan(obs, target)).mean()), 4)}
    return rows


def fresh_goal_matcher(init: str, out: str, seed: int) -> str:
    """A copy of weights file ``init`` whose Goal Matcher (actor only) starts from random weights (seed ``seed``),
    written to ``out``; the executor and the critics are ``init``'s."""
    nets, rec = load_weights(init, any_scenario=True)
    torch.manual_seed(seed)
    fresh = type(nets)(nets.config)
    nets.gm.load_state_dict(fresh.gm.state_dict())
    save_weights(out, nets, rec["scenario"])
    return out


def run_train(args) -> None:
    layouts = validation_layouts(args.layouts, args.seed)
    if args.fresh_goal_matcher and not args.resume:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        args.init = fresh_goal_matcher(args.init, str(Path(args.out).parent / (Path(args.out).name + "-init.pt")),
                                       args.train_seed)
    sets = ["imitate=h-bottleneck", "train_executor=false",
            f"updates={args.updates}", f"num_envs={args.worlds}", f"lr={args.lr}", "eval_every=0",
            f"eval_episodes={args.eval_episodes}", f"checkpoint_every={args.measure_every}", *args.set]
    method, cfg, overrides = method_config("masp-minmax", sets, args.scenario)
    t0 = time.perf_counter()

    def report(trainer):
        if trainer.iterations % args.measure_every == 0 or trainer.iterations == 1:
            row = trainer.last_row
            print(json.dumps({"iteration": trainer.iterations, "wall_s": round(time.perf_counter() - t0, 1),
                              "loss": round(row["gm_policy_loss"], 4), "entropy": round(row["gm_entropy"], 4),
                              **measure(trainer.nets, layouts)}), flush=True)

    manifest = train(args.scenario, cfg, args.out, seed=args.train_seed, resume=args.resume,
                     init=None if args.resume else args.init, overrides=overrides, progress=False,
                     on_iteration=report, method=method,
                     trainer_type=trainer_type(args.loss, args.credit, args.states))
    print(json.dumps({"final_eval": manifest["final_eval"], "wall_clock_s": manifest["wall_clock_s"]}), flush=True)


def run_measure(args) -> None:
    layouts = validation_layouts(args.layouts, args.seed)
    for path in args.checkpoints:
        nets, _ = load_weights(path, any_scenario=True)
        print(json.dumps({"weights": path, **measure(nets.eval(), layouts)}), flush=True)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=100, help="evaluation seed of the validation layouts (100+)")
    parser.add_argument("--layouts", type=int, default=100, help="validation layouts per scenario")
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train")
    t.add_argument("--scenario", default="mpe-50")
    t.add_argument("--loss", default="decoding", choices=("decoding", "sequential", "independent"))
    t.add_argument("--states", default="spawn", choices=("spawn", "rollout"))
    t.add_argument("--credit", default="teacher", choices=("teacher", "within"))
    t.add_argument("--updates", type=int, default=300)
    t.add_argument("--worlds", type=int, default=32)
    t.add_argument("--lr", type=float, default=7e-4)
    t.add_argument("--measure-every", type=int, default=50)
    t.add_argument("--eval-episodes", type=int, default=20)
    t.add_argument("--init", default="masp_lite/weights/mpe-20.pt")
    t.add_argument("--train-seed", type=int, default=0)
    t.add_argument("--resume", action="store_true", help="continue the run in --out (--updates may grow)")
    t.add_argument("--fresh-goal-matcher", action="store_true", help="the Goal Matcher from random weights")
    t.add_argument("--set", action="append", default=[], help="further training settings or overrides")
    t.add_argument("--out", required=True)
    m = sub.add_parser("measure")
    m.add_argument("checkpoints", nargs="+")
    args = parser.parse_args(argv)
    if args.seed < 100:
        parser.error("--seed: validation layouts come from evaluation seeds 100 and above")
    torch.set_num_threads(1)
    (run_train if args.command == "train" else run_measure)(args)


if __name__ == "__main__":
    main()
