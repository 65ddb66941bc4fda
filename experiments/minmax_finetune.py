"""Which fine-tune after the imitation keeps its min-max gain? (``masp-minmax``'s RL stage.)

Usage (from the repository root)::

    python -m experiments.minmax_finetune --init RUN/imitate-mpe-50/weights.pt --variant anchor \\
        --updates 20 --save-every 5 --out runs/ft-anchor
    python -m masp_lite evaluate --method masp-minmax --scenario mpe-50 --checkpoint runs/ft-anchor/it-5.pt \\
        --seeds 100 101 102 --episodes 100 --set any_scenario=true

It runs an RL stage after the imitation (MAPPO on R_GM, the Goal Matcher alone, 16 worlds, at a fine-tune's step
size 2e-4, entropy 0.005, 4 epochs) from ``--init`` and writes the weights every ``--save-every`` iterations
(``it-K.pt``; iteration 0 is ``--init`` itself) for ``evaluate`` on validation layouts (seeds 100+). Variants:

* ``paper``: the paper's training of the Goal Matcher, as MASP's fine-tuning stages run it;
* ``anchor``: the same, and after every PPO update one pass of the imitation's margin loss
  (:meth:`masp_lite.algos.imitation.ImitationTrainer.imitation_pass`, h-bottleneck's labels) over the Goal
  Matcher's states of the same rollout, times ``--anchor``: RL that may move the assignment only where
  the decoding keeps the teacher's longest trip (an imitation term kept beside the policy gradient, as
  demonstration-augmented policy gradients do).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from masp_lite.algos.imitation import ImitationTrainer
from masp_lite.algos.masp_trainer import MASPTrainer
from masp_lite.nets.goal_draw import sequential_sample
from masp_lite.recipes import EVAL_SETTINGS
from masp_lite.training import method_config, train
from masp_lite.weights import save_weights


class Anchored(ImitationTrainer):
    """MAPPO's iteration (the paper's draw and update), then the imitation's margin pass on its rollout's states."""

    draw_goals = staticmethod(sequential_sample)
    anchor = 1.0

    def collect(self):
        gm_data, cae_data, stats = MASPTrainer.collect(self)
        self.states = {k: gm_data[k].flatten(0, 1) for k in self.obs_keys}
        return gm_data, cae_data, stats

    def iteration(self):
        row = MASPTrainer.iteration(self)
        self.margin, _ = self.imitation_pass(self.states, self.anchor)
        return row


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--init", required=True, help="the imitation's weights (an imitate-<preset> stage's)")
    p.add_argument("--preset", default="mpe-50")
    p.add_argument("--variant", default="paper", choices=("paper", "anchor"))
    p.add_argument("--anchor", type=float, default=1.0, help="the margin pass's weight (variant anchor)")
    p.add_argument("--updates", type=int, default=20)
    p.add_argument("--save-every", type=int, default=5)
    p.add_argument("--train-seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], help="further training settings")
    p.add_argument("--out", required=True)
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    fine_tune = {"train_executor": False, "lr": 2e-4, "entropy_coef": 0.005, "gm_ppo_epochs": 4,
                 "gm_reference": "squared", **EVAL_SETTINGS, "num_envs": 16}
    sets = [f"updates={a.updates}", "eval_every=0", f"checkpoint_every={a.save_every}", *a.set]
    if a.variant == "anchor":
        sets += ["imitate=h-bottleneck"]
    method, cfg, overrides = method_config("masp-minmax", [*(f"{k}={v}" for k, v in fine_tune.items()), *sets],
                                           a.preset)
    trainer = type("AnchoredRun", (Anchored,), {"anchor": a.anchor}) if a.variant == "anchor" else None
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    def report(tr):
        row = tr.last_row
        print(json.dumps({"iteration": tr.iterations, "wall_s": round(time.perf_counter() - t0, 1),
                          "train_sr": round(row["train_sr"], 3), "train_steps": round(row["train_steps"], 2),
                          "gm_reward": round(row["gm_reward"], 4), "gm_entropy": round(row["gm_entropy"], 3),
                          "margin": round(getattr(tr, "margin", float("nan")), 4)}), flush=True)
        if tr.iterations % a.save_every == 0:
            save_weights(out / f"it-{tr.iterations}.pt", tr.nets, a.preset)

    manifest = train(a.preset, cfg, out / "run", seed=a.train_seed, init=a.init, overrides=overrides,
                     progress=False, on_iteration=report, method=method, trainer_type=trainer)
    print(json.dumps({"wall_clock_s": manifest["wall_clock_s"]}), flush=True)


if __name__ == "__main__":
    main()
