"""``python -m masp_lite train --method masp --scenario mpe-20 [--out DIR] [--resume] [--seed S] [--set k=v]``,
or ``python -m masp_lite train --recipe masp [--stage mpe-20] [--seed S] [--out DIR]``.

``--recipe NAME`` trains a recipe of :mod:`masp_lite.recipes` (how every kept weights file is
made): every stage in turn in ``--out/STAGE/`` (default ``runs/recipe-NAME-seedS``), skipping
finished stages and resuming a stopped one, so the same command continues a killed recipe;
``--stage`` trains one stage, from the weights of the stage it starts from in ``--out`` (or
``--init``). Only the evaluation and checkpoint settings may be ``--set`` then.

Trains MASP, an ablation or an RL baseline (``--method``, settings from
:func:`masp_lite.training.method_config`) with :func:`masp_lite.training.train` (run folder,
exact resume, manifest).
``--set`` takes any training setting (:class:`masp_lite.config.TrainConfig`'s fields, e.g.
``--set updates=300 --set lr=2e-4``) or scenario override (``--set num_obstacles=40``),
parsed by :func:`masp_lite.parsing.parse_sets` as in every command. ``--init PATH`` starts
from a weights file (fine-tuning).

The progress bar shows the training rollouts (sampled actions) and the last periodic
evaluation (deterministic policies); the closing line is the final evaluation. Ctrl-C stops
the run without a traceback: the last checkpoint (``state.pt``, written atomically) is read
back to check it is whole, and the exact command that resumes it is printed (exit status 130).
"""
from __future__ import annotations

import os
import shlex
import sys

import torch

from ..envs import get_scenario
from ..envs.checks import check_seed
from ..recipes import get_recipe, recipe_names, run_recipe
from ..threads import TRAIN_THREADS
from ..training import RunWriteError, checkpoint_iterations, method_config, train

__all__ = ["add_arguments", "run", "resume_command", "EXAMPLES", "MAX_THREADS"]

#: The most torch threads ``--threads`` takes (or this machine's cores, when it has more).
MAX_THREADS = 64

EXAMPLES = [
    "train --method masp --scenario mpe-20 --out runs/mpe-20 --seed 0 --set lr=2e-4",
    "train --method masp --scenario mpe-20 --out runs/mpe-20 --resume   # continue it after Ctrl-C",
    "train --method h-mappo --scenario mpe-5 --seed 0   # an RL baseline, same trainer",
    "train --recipe masp --seed 0   # the shipped MASP from random networks, every stage in turn",
]


def add_arguments(parser) -> None:
    parser.add_argument("--method", default=None, help="learned method to train: masp, an ablation (masp-rg, gm-mlp, "
                        "cae-mlp), a baseline (h-mappo, htamp, mage-x, mappo, darl1n) or masp-minmax (beyond the "
                        "paper); default: the one the --set values make, masp without any")
    parser.add_argument("--scenario", default=None, help="scenario, e.g. mpe-20 (not with --recipe)")
    parser.add_argument("--recipe", default=None,
                        help=f"train a recipe (masp_lite.recipes): {', '.join(recipe_names())}")
    parser.add_argument("--stage", default=None, help="with --recipe: only this stage (e.g. mpe-20)")
    parser.add_argument("--out", default=None, help="run folder (default runs/METHOD-SCENARIO-seedS)")
    parser.add_argument("--resume", action="store_true", help="continue the run saved in --out")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                        help="a training setting (masp_lite.config) or scenario override; repeatable")
    parser.add_argument("--init", default=None, help="start from this weights file (fine-tuning)")
    parser.add_argument("--threads", type=int, default=TRAIN_THREADS,
                        help=f"torch threads (default {TRAIN_THREADS}; they wait passively, see masp_lite.threads)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _python() -> str:
    """This interpreter as a command: relative to the current folder when inside it (``.venv/bin/python``)."""
    rel = os.path.relpath(sys.executable)
    return rel if not rel.startswith("..") else sys.executable


def resume_command(args, out: str) -> str:
    """The command line that continues this run: the same scenario, seed and settings, ``--resume``."""
    parts = [_python(), "-m", "masp_lite", "train", "--method", args.method, "--scenario", args.scenario,
             "--out", out, "--seed", str(args.seed)]
    parts += [x for s in args.sets for x in ("--set", s)]
    parts += ["--threads", str(args.threads)] if args.threads != TRAIN_THREADS else []
    parts += ["--quiet"] if args.quiet else []
    return shlex.join([*parts, "--resume"])


def _interrupted(args, out: str, cfg) -> str:
    try:
        done = checkpoint_iterations(out)
    except ValueError as e:
        return f"interrupted; the training state in {out} does not load ({e})"
    if done is None:
        return (f"interrupted before the first checkpoint (one every {cfg.run.checkpoint_every} iterations): "
                f"nothing to resume in {out}; run the same command again to start over")
    return (f"interrupted; the last checkpoint, iteration {done} of {cfg.run.updates}, is whole in "
            f"{os.path.join(out, 'state.pt')}. Resume the run with:\n  {resume_command(args, out)}")


def _run_recipe(args) -> int:
    """``train --recipe``: the recipe's stages (or one) for ``--seed``; one clear error for a bad combination."""
    given = [f"--{k}" for k in ("scenario", "method") if getattr(args, k) is not None] + \
        (["--resume"] if args.resume else [])
    if given:
        raise ValueError(f"train --recipe: {', '.join(given)} come from the recipe (a stopped recipe resumes by "
                         "itself); leave them out")
    recipe = get_recipe(args.recipe)
    if args.stage is not None:
        recipe.stage(args.stage)  # an unknown stage: one clear error before anything is written
    out = args.out or f"runs/recipe-{recipe.name}-seed{args.seed}"
    try:
        m = run_recipe(recipe, args.seed, out, stage=args.stage, init=args.init, sets=args.sets,
                       progress=not args.quiet, say=lambda text: print(text, file=sys.stderr))
    except KeyboardInterrupt:
        print(f"\ninterrupted; run the same command again to resume recipe {recipe.name} in {out}", file=sys.stderr)
        return 130
    except RunWriteError as e:  # disk full, read-only: the same command goes on once it can write
        raise ValueError(f"{e}; once it can be written, run the same command again") from None
    ev = m["final_eval"]
    print(f"recipe {recipe.name}, last stage on {m['scenario']}: SR {ev['sr']:.3f}  Steps {ev['steps']:.2f}  "
          f"CR {ev['cr']:.3f} -> {out}")
    return 0


def run(args) -> int:
    most = max(MAX_THREADS, os.cpu_count() or 1)
    if not 1 <= args.threads <= most:  # thousands of threads stall the machine rather than speed anything up
        raise ValueError(f"--threads: expected an int from 1 to {most}, got {args.threads}")
    check_seed(args.seed, "--seed")
    if args.out is not None and not args.out.strip():
        raise ValueError("--out: expected a folder path such as runs/mpe-20, got an empty string")
    if args.recipe is not None:
        torch.set_num_threads(args.threads)
        return _run_recipe(args)
    if args.stage is not None:
        raise ValueError("train --stage: expected --recipe NAME as well (a stage belongs to a recipe)")
    if args.scenario is None:
        raise ValueError("train: expected --scenario SCENARIO (or --recipe NAME)")
    preset = get_scenario(args.scenario)  # the one lookup of the name; train applies the overrides to it
    args.method, cfg, overrides = method_config(args.method, args.sets, preset)
    torch.set_num_threads(args.threads)
    out = args.out or f"runs/{args.method}-{args.scenario}-seed{args.seed}"
    command = "python -m masp_lite train " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "train" else None
    try:
        m = train(preset, cfg, out, seed=args.seed, resume=args.resume, init=args.init,
                  overrides=overrides, progress=not args.quiet, command=command, method=args.method)
    except KeyboardInterrupt:  # Ctrl-C: no traceback; say where the run stands and how to go on
        print(f"\n{_interrupted(args, out, cfg)}", file=sys.stderr)
        return 130
    except RunWriteError as e:  # disk full, read-only: one line with the command that goes on once it can write
        resume = resume_command(args, out) if e.last_checkpoint is not None else None
        raise ValueError(f"{e}; once it can be written, " + (f"resume with: {resume}" if resume else
                         "run the same command again")) from None
    ev = m["final_eval"]
    print(f"{args.method} on {m['scenario']}, final evaluation (deterministic, {ev['episodes']} episodes): "
          f"SR {ev['sr']:.3f}  Steps {ev['steps']:.2f}  CR {ev['cr']:.3f}  "
          f"({m['env_steps']} env steps, {m['wall_clock_s']:.0f} s) -> {out}")
    return 0
