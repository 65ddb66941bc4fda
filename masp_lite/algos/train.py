"""``python -m masp_lite train --method masp --scenario mpe-20 [--out DIR] [--resume] [--seed S] [--set k=v]``.

Trains MASP (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) and writes, in ``--out``
(default ``runs/masp-SCENARIO-seedS``):

* ``state.pt`` — the full training state (weights, optimizers, value norms, every RNG
  state), saved atomically (temporary file + ``os.replace``) every ``checkpoint_every``
  iterations; ``--resume`` continues from it and ends with exactly the parameters an
  uninterrupted run would have (the RNG states make the rest of the run identical);
* ``weights.pt`` — the latest networks in the shipped format (:mod:`masp_lite.checkpoints`);
* ``progress.csv`` — one row per iteration: env steps, wall-clock, training SR/Steps/CR,
  mean rewards, losses and entropies of both levels, and the periodic evaluation
  (deterministic policies, ``eval_episodes`` episodes, fixed evaluation seed);
* ``manifest.json`` — the first command, the last one (a resume), seed, configuration, env
  steps, wall-clock (summed over resumes), machine and the final evaluation. A run can be
  ended early by resuming it with ``--set updates=N`` (N = iterations done): nothing in the
  schedule depends on ``updates``, so the manifest's configuration then reproduces it.

``--set`` takes any :class:`~masp_lite.algos.mappo.MAPPOConfig` field or scenario override
(``--set updates=300 --set num_envs=32``). ``--init PATH`` starts from a weights file
(fine-tuning, e.g. mpe-50 from the mpe-20 weights); weights without ``neighbour_goals``
start a run that has it through :meth:`~masp_lite.nets.policies.MASPNets.with_neighbour_goals`
(same behaviour, the new inputs weighted 0). Refused with one clear error, nothing
overwritten: an unknown method, field or value; ``--resume`` without ``state.pt``; an
existing ``state.pt`` without ``--resume``; a corrupt state; a state trained with another
scenario or configuration (only ``updates`` may grow on resume).
"""
from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import platform
import shlex
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import torch

from ..checkpoints import atomic_write_bytes, load_weights, save_weights, sha256
from .mappo import MAPPOConfig

__all__ = ["add_arguments", "run", "train", "parse_config", "evaluate_nets", "ship_run", "CSV_FIELDS"]

CSV_FIELDS = ["iteration", "env_steps", "wall_s", "train_sr", "train_steps", "train_cr", "gm_reward", "cae_reward",
              "gm_policy_loss", "gm_value_loss", "gm_entropy", "cae_policy_loss", "cae_value_loss", "cae_entropy",
              "eval_sr", "eval_steps", "eval_cr"]
EVAL_SEED = 12_345


def parse_config(sets) -> tuple[MAPPOConfig, dict]:
    """``KEY=VALUE`` strings -> (MAPPOConfig, scenario overrides)."""
    from ..envs import OVERRIDES
    fields = {f.name: f for f in dataclasses.fields(MAPPOConfig)}
    cfg, overrides = {}, {}
    for item in sets or []:
        key, sep, text = item.partition("=")
        if not sep:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE")
        if key in fields:
            typ = fields[key].type if isinstance(fields[key].type, type) else eval(fields[key].type)  # noqa: S307
            try:
                if typ is bool:  # bool("False") is True: read the word
                    if text.lower() not in ("true", "false"):
                        raise ValueError(text)
                    cfg[key] = text.lower() == "true"
                else:
                    cfg[key] = typ(float(text)) if typ is int and float(text).is_integer() else typ(text)
            except ValueError:
                raise ValueError(f"--set {key}={text!r}: expected a {typ.__name__}") from None
        elif key in OVERRIDES:
            overrides[key] = OVERRIDES[key](text)
        else:
            raise ValueError(f"--set {key!r}: unknown; expected a training field {sorted(fields)} "
                             f"or a scenario override {sorted(OVERRIDES)}")
    return MAPPOConfig(**cfg), overrides


def evaluate_nets(nets, scenario, overrides=None, episodes: int = 32, seed: int = EVAL_SEED) -> dict:
    """SR, Steps and CR of the deterministic policies over ``episodes`` episodes (means)."""
    from ..envs import make
    from ..eval import collision_rate, rollout, steps, success_rate
    from ..nets.policies import MASPPolicy
    world = make(scenario, num_envs=min(episodes, 100), seed=seed, **(overrides or {}))
    was = nets.training
    nets.eval()
    log, dt = rollout(world, MASPPolicy.from_nets(world, nets, seed=seed), episodes, seed)
    nets.train(was)
    return {"sr": float(success_rate(log).mean()), "steps": float(steps(log).mean()),
            "cr": float(collision_rate(log).mean()), "decision_ms": dt * 1e3}


def _save_state(path: Path, state: dict) -> None:
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write_bytes(path, buf.getvalue())


def _load_state(path: Path) -> dict:
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:
        raise ValueError(f"{path}: expected a training state saved by 'train', could not read it "
                         f"({type(e).__name__})") from None


def _write_csv(path: Path, rows: list[dict]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    atomic_write_bytes(path, buf.getvalue().encode())


def _read_csv(path: Path, upto: int) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return [r for r in csv.DictReader(f) if int(r["iteration"]) <= upto]


def train(scenario: str, cfg: MAPPOConfig, out, seed: int = 0, resume: bool = False, init=None,
          overrides: dict | None = None, progress: bool = True, command: str | None = None,
          on_iteration=None) -> dict:
    """Train MASP; returns the manifest. ``on_iteration(trainer)`` runs after every iteration."""
    from .masp_trainer import MASPTrainer
    out = Path(out)
    state_path = out / "state.pt"
    if resume and not state_path.exists():
        raise ValueError(f"--resume: expected a training state at {state_path}, found none")
    if not resume and state_path.exists():
        raise ValueError(f"{state_path} exists; pass --resume to continue it or choose another --out")
    trainer = MASPTrainer(scenario, cfg, seed=seed, overrides=overrides)
    wall_before, rows, started = 0.0, [], datetime.now(timezone.utc).isoformat(timespec="seconds")
    default_command = f"python -m masp_lite train --method masp --scenario {scenario} --seed {seed}"
    first_command = None
    if resume:
        state = _load_state(state_path)
        saved = dict(state.get("config", {}))
        now = dataclasses.asdict(cfg)
        defaults = dataclasses.asdict(MAPPOConfig())  # a field added since the state was saved has its default
        diff = sorted(k for k in now if k != "updates" and saved.get(k, defaults[k]) != now[k])
        if state.get("scenario") != trainer.world.scenario.name or state.get("overrides", {}) != (overrides or {}):
            raise ValueError(f"{state_path} was trained on {state.get('scenario')!r} {state.get('overrides')}; "
                             f"expected {trainer.world.scenario.name!r} {overrides or {}}")
        if diff or int(state.get("seed", -1)) != int(seed):
            raise ValueError(f"{state_path}: expected the same seed and settings as the interrupted run; "
                             f"differs in {diff or ['seed']}")
        trainer.load_state_dict(state)
        wall_before, started = float(state["wall_s"]), state["started"]
        first_command = state.get("command")
        init = state.get("init") or init
        rows = _read_csv(out / "progress.csv", trainer.iterations)
    elif init is not None:
        nets, rec = load_weights(init, any_scenario=True)
        if nets.arch != trainer.nets.arch and {**nets.arch, "neighbour_goals": True} == trainer.nets.arch:
            nets = nets.with_neighbour_goals()  # same behaviour, new inputs weighted 0
        if nets.arch != trainer.nets.arch:
            raise ValueError(f"--init {init}: architecture {nets.arch} differs from the configured {trainer.nets.arch}")
        trainer.nets.load_state_dict(nets.state_dict())
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    wall = lambda: wall_before + time.perf_counter() - t0  # noqa: E731
    sc = trainer.world.scenario.name

    def save():
        st = trainer.state_dict()
        st.update(scenario=sc, overrides=dict(overrides or {}), wall_s=wall(), started=started,
                  command=first_command or command or default_command, init=str(init) if init is not None else "")
        _save_state(state_path, st)
        save_weights(out / "weights.pt", trainer.nets, sc)
        _write_csv(out / "progress.csv", rows)

    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=cfg.updates, initial=trainer.iterations, unit="it", desc=f"masp on {sc}")
    try:
        while trainer.iterations < cfg.updates:
            row = trainer.iteration()
            row["wall_s"] = round(wall(), 2)
            if cfg.eval_every and trainer.iterations % cfg.eval_every == 0:
                ev = evaluate_nets(trainer.nets, sc, overrides, cfg.eval_episodes)
                row.update({f"eval_{k}": ev[k] for k in ("sr", "steps", "cr")})
            rows.append({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()})
            if bar is not None:
                bar.update(1)
                bar.set_postfix(sr=f"{row['train_sr']:.2f}", steps=f"{row['train_steps']:.1f}",
                                cr=f"{row['train_cr']:.2f}")
            if trainer.iterations % cfg.checkpoint_every == 0 or trainer.iterations == cfg.updates:
                save()
            if on_iteration is not None:
                on_iteration(trainer)
    finally:
        if bar is not None:
            bar.close()
    final = evaluate_nets(trainer.nets, sc, overrides, cfg.eval_episodes)
    manifest = {
        "method": "masp", "scenario": sc, "overrides": dict(overrides or {}), "seed": int(seed),
        "command": first_command or command or default_command,
        "last_command": command or default_command,
        "init": str(init) if init is not None else None, "config": dataclasses.asdict(cfg),
        "arch": dict(trainer.nets.arch), "iterations": trainer.iterations, "env_steps": trainer.env_steps,
        "wall_clock_s": round(wall(), 1), "started": started,
        "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "torch": torch.__version__,
                    "torch_threads": torch.get_num_threads()},
        "final_eval": {"episodes": cfg.eval_episodes, "seed": EVAL_SEED, **final},
        "weights_sha256": sha256(out / "weights.pt"),
    }
    atomic_write_bytes(out / "manifest.json", (json.dumps(manifest, indent=2) + "\n").encode())
    return manifest


_RUN_INFO = ("command", "seed", "init", "iterations", "env_steps", "wall_clock_s", "started", "finished", "machine",
             "config", "final_eval")
_RUN_EXTRA = ("last_command", "overrides")  # present in the manifests of resumed runs / runs with overrides


def _run_info(m: dict) -> dict:
    return {**{k: m[k] for k in _RUN_INFO}, **{k: m[k] for k in _RUN_EXTRA if k in m}}


def ship_run(run_dir, evaluation: dict | None = None, note: str | None = None, earlier=()) -> dict:
    """Copy a finished run's ``weights.pt`` into :mod:`masp_lite.checkpoints` and record it in the manifest.

    The entry keeps the run's manifest (command, seed, env steps, wall-clock, machine, final
    evaluation) plus the SHA-256 of the copied file, the run's ``progress.csv`` (copied as
    ``<scenario>.progress.csv``), an optional ``evaluate()`` record and a free-text ``note``
    (e.g. the machine's load while it trained).

    ``earlier``: the stages this run was fine-tuned from, oldest first, each a pair of
    paths ``(manifest.json, progress.csv)`` of a finished run. They are recorded under
    ``stages`` (their run information, and their curves copied as
    ``<scenario>.stageK.progress.csv``), so the shipped weights' whole training history —
    from scratch to the last fine-tuning — stays with them.
    """
    from ..checkpoints import HERE, MANIFEST, read_weights
    run_dir = Path(run_dir)
    if not (run_dir / "manifest.json").exists():
        raise ValueError(f"{run_dir}: expected a finished run (manifest.json)")
    m = json.loads((run_dir / "manifest.json").read_text())
    rec = read_weights(run_dir / "weights.pt")
    name = rec["scenario"]
    stages = []
    for k, (stage_manifest, stage_progress) in enumerate(earlier, start=1):
        sm = json.loads(Path(stage_manifest).read_text())
        missing = [key for key in _RUN_INFO if key not in sm]
        if missing:
            raise ValueError(f"{stage_manifest}: expected a run manifest; missing {missing}")
        target = f"{name}.stage{k}.progress.csv"
        atomic_write_bytes(HERE / target, Path(stage_progress).read_bytes())
        stages.append({"scenario": sm.get("scenario"), "training": _run_info(sm),
                       "progress": target})
    data = (run_dir / "weights.pt").read_bytes()
    atomic_write_bytes(HERE / f"{name}.pt", data)
    progress = None
    if (run_dir / "progress.csv").exists():  # the training curves travel with the weights
        progress = f"{name}.progress.csv"
        atomic_write_bytes(HERE / progress, (run_dir / "progress.csv").read_bytes())
    manifest = json.loads(MANIFEST.read_text()) if MANIFEST.exists() else {}
    run_info = _run_info(m)
    manifest[name] = {"file": f"{name}.pt", "sha256": sha256(HERE / f"{name}.pt"), "scenario": name,
                      "arch": rec["arch"], "training": run_info, "evaluation": evaluation, "note": note,
                      "progress": progress, "stages": stages}
    atomic_write_bytes(MANIFEST, (json.dumps(manifest, indent=2, sort_keys=True) + "\n").encode())
    return manifest[name]


def add_arguments(parser) -> None:
    parser.add_argument("--method", default="masp", help="learned method to train (only 'masp' here)")
    parser.add_argument("--scenario", required=True, help="particle scenario, e.g. mpe-20")
    parser.add_argument("--out", default=None, help="run folder (default runs/masp-SCENARIO-seedS)")
    parser.add_argument("--resume", action="store_true", help="continue the run saved in --out")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                        help="a MAPPOConfig field or scenario override; repeatable")
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
