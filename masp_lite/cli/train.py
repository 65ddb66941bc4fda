"""``python -m masp_lite train --method masp --scenario mpe-20 [--out DIR] [--resume] [--seed S] [--set k=v]``.

Trains MASP with :func:`masp_lite.training.train` (run folder, exact resume, manifest).
``--set`` takes any training setting (:class:`masp_lite.config.TrainConfig`'s fields, e.g.
``--set updates=300 --set lr=2e-4``) or scenario override (``--set num_obstacles=40``),
parsed by :func:`masp_lite.config.parse_sets` as in every command. ``--init PATH`` starts
from a weights file (fine-tuning).
"""
from __future__ import annotations

import shlex
import sys

import torch

from ..training import parse_config, train

__all__ = ["add_arguments", "run"]


def add_arguments(parser) -> None:
    parser.add_argument("--method", default="masp", help="learned method to train (only 'masp' here)")
    parser.add_argument("--scenario", required=True, help="particle scenario, e.g. mpe-20")
    parser.add_argument("--out", default=None, help="run folder (default runs/masp-SCENARIO-seedS)")
    parser.add_argument("--resume", action="store_true", help="continue the run saved in --out")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                        help="a training setting (masp_lite.config) or scenario override; repeatable")
    parser.add_argument("--init", default=None, help="start from this weights file (fine-tuning)")
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    if args.method != "masp":
        raise ValueError(f"train: unknown method {args.method!r}; expected 'masp'")
    if args.threads < 1:
        raise ValueError(f"--threads: expected a positive int, got {args.threads}")
    torch.set_num_threads(args.threads)
    cfg, overrides = parse_config(args.sets)
    out = args.out or f"runs/masp-{args.scenario}-seed{args.seed}"
    command = "python -m masp_lite train " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "train" else None
    m = train(args.scenario, cfg, out, seed=args.seed, resume=args.resume, init=args.init, overrides=overrides,
              progress=not args.quiet, command=command)
    ev = m["final_eval"]
    print(f"masp on {m['scenario']}: SR {ev['sr']:.3f}  Steps {ev['steps']:.2f}  CR {ev['cr']:.3f}  "
          f"({m['env_steps']} env steps, {m['wall_clock_s']:.0f} s) -> {out}")
    return 0
