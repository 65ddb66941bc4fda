"""Training runs: a folder that survives being killed, a manifest, and shipping the weights.

:func:`train` runs MASP (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) and writes, in
its run folder (``python -m masp_lite train`` defaults to ``runs/masp-SCENARIO-seedS``):

* ``state.pt`` — the full training state (weights, optimizers, value norms, every RNG
  state), saved atomically (temporary file + ``os.replace``) every ``checkpoint_every``
  iterations, after the two files below, so that a run stopped at any moment (Ctrl-C,
  a kill) leaves a whole state that agrees with them; ``--resume`` continues from it and
  ends with exactly the parameters an uninterrupted run would have (the RNG states make
  the rest of the run identical);
* ``weights.pt`` — the latest networks in the shipped format (:mod:`masp_lite.weights`);
* ``progress.csv`` — one row per iteration: env steps, wall-clock, training SR/Steps/CR,
  mean rewards, losses and entropies of both levels, and the periodic evaluation
  (deterministic policies, ``eval_episodes`` episodes, fixed evaluation seed);
* ``manifest.json`` — the first command, the last one (a resume), seed, configuration, env
  steps, wall-clock (summed over resumes), machine and the final evaluation. A run can be
  ended early by resuming it with ``--set updates=N`` (N = iterations done): nothing in the
  schedule depends on ``updates``, so the manifest's configuration then reproduces it.

The configuration is a :class:`~masp_lite.config.TrainConfig`. ``init`` starts from a
weights file of the same architecture (fine-tuning, e.g. mpe-50 from the mpe-20 weights).
Refused with one clear error, nothing overwritten: ``resume`` without ``state.pt``; an
existing ``state.pt`` without ``resume``; a corrupt state; a state trained with another
scenario or configuration (only ``updates`` may grow on resume).

:func:`ship_run` copies a finished run's weights into a weights folder (the source
tree's ``masp_lite/weights/``, given explicitly: nothing is written into an installed
package) and its whole history (manifests and curves of every stage) into a history
folder (``results/training/``).
"""
from __future__ import annotations

import csv
import io
import json
import os
import platform
import time
from datetime import datetime, timezone
from pathlib import Path

import torch

from .algos.drone_trainer import DroneMASPTrainer
from .algos.masp_trainer import MASPTrainer
from .config import TrainConfig
from .envs import OVERRIDES, Scenario, get_scenario, make
from .evaluation import collision_rate, rollout, steps, success_rate
from .parsing import field_types, parse_sets
from .policies.drone_masp import DRONE_METHODS, DroneMASPPolicy
from .policies.masp import METHOD_SETTINGS, VARIANTS, MASPPolicy
from .weights import atomic_write_bytes, load_weights, read_weights, save_weights, sha256, trained_world

__all__ = ["train", "parse_config", "method_config", "evaluate_nets", "checkpoint_iterations", "ship_run",
           "ship_zero_shot",
           "CSV_FIELDS", "EVAL_SEED"]

CSV_FIELDS = ["iteration", "env_steps", "wall_s", "train_sr", "train_steps", "train_cr", "gm_reward", "cae_reward",
              "gm_policy_loss", "gm_value_loss", "gm_entropy", "cae_policy_loss", "cae_value_loss", "cae_entropy",
              "eval_sr", "eval_steps", "eval_cr"]
EVAL_SEED = 12_345


def method_config(method: str | None, sets=(), scenario: str | None = None) -> tuple[str, TrainConfig, dict]:
    """``(method, config, scenario overrides)`` of ``train [--method METHOD] --set ...``.

    The configuration is the method's settings (:data:`METHOD_SETTINGS`), then ``sets``.
    Without a method, the one whose settings ``sets`` give is meant (``--set
    goal_matcher=random`` is ``masp-rg``, as the ablations' manifests were written), MASP by
    default. One clear error for a method that is not trained here, a ``--set`` that would
    make it another method, or a scenario the trainer does not run (drones).
    """
    if scenario is not None and get_scenario(scenario).kind == "drone":
        return _drone_method_config(method, sets, scenario)
    if method is None:
        cfg, _ = parse_config(sets)
        got = {k: getattr(cfg.net, k) for k in ("goal_matcher", "executor")}
        match = [m for m, v in VARIANTS.items() if v == got]
        if not match:
            raise ValueError(f"train: no method has the settings {got}; expected one of "
                             + "; ".join(f"{m} {v}" for m, v in VARIANTS.items()))
        method = match[0]
    if method not in METHOD_SETTINGS:
        raise ValueError(f"train: {method!r} is not a method trained here; expected one of {sorted(METHOD_SETTINGS)}")
    if "action" in dict(s.split("=", 1) for s in sets if "=" in s):
        raise ValueError("train: --set action is for drone scenarios (drone-*); particle networks take MPE's "
                         "discrete actions")
    own = METHOD_SETTINGS[method]
    cfg, overrides = parse_config([f"{k}={v}" for k, v in own.items()] + list(sets))
    for k in VARIANTS[method]:
        if getattr(cfg.net, k) != own[k]:
            raise ValueError(f"train --method {method}: {k} is {own[k]!r} for this method; --set {k}="
                             f"{getattr(cfg.net, k)} makes another one (see masp_lite.policies.masp.VARIANTS)")
    return method, cfg, overrides


def _layout(arch: dict) -> dict:
    """The settings that decide the networks' parameters: a stage may change the others (the Goal
    Matcher's period; Hungarian or random goals to a trained Goal Matcher, whose networks exist in
    every weights file) and start from the weights of the stage before (``--init``)."""
    same_networks = {"graph": "graph", "hungarian": "graph", "random": "graph"}
    out = {k: v for k, v in arch.items() if k != "global_step"}
    out["goal_matcher"] = same_networks.get(arch["goal_matcher"], arch["goal_matcher"])
    return out


def _drone_method_config(method, sets, scenario) -> tuple[str, TrainConfig, dict]:
    """:func:`method_config` for a drone scenario: ``masp`` (motor commands) or ``masp-velocity``."""
    given = dict(s.split("=", 1) for s in sets if "=" in s)
    if method is None:
        method = "masp-velocity" if given.get("action") == "velocity" else "masp"
    if method not in DRONE_METHODS:
        raise ValueError(f"train --method {method}: drone scenarios ({scenario!r}) train {sorted(DRONE_METHODS)}")
    action = DRONE_METHODS[method]
    if given.get("action", action) != action:
        raise ValueError(f"train --method {method}: action is {action!r} for this method; --set action="
                         f"{given['action']} makes another one ({sorted(DRONE_METHODS)})")
    cfg, overrides = parse_config([f"action={action}", *sets])
    return method, cfg, overrides


def parse_config(sets) -> tuple[TrainConfig, dict]:
    """``KEY=VALUE`` strings -> (TrainConfig, scenario overrides), by :func:`masp_lite.parsing.parse_sets`."""
    types = field_types(Scenario)
    got = parse_sets(sets, {"training setting": field_types(TrainConfig),
                            "scenario override": {k: types[k] for k in OVERRIDES}})
    return TrainConfig.from_flat(got["training setting"]), got["scenario override"]


def evaluate_nets(nets, scenario, overrides=None, episodes: int = 32, seed: int = EVAL_SEED) -> dict:
    """SR, Steps and CR of the deterministic policies over ``episodes`` episodes (means)."""
    world = make(scenario, num_envs=min(episodes, 100), seed=seed, **(overrides or {}))
    was = nets.training
    nets.eval()
    cls = DroneMASPPolicy if nets.config.world == "drone" else MASPPolicy
    log, dt = rollout(world, cls.from_nets(world, nets, seed=seed), episodes, seed)
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


def _bar_text(row: dict, rows: list[dict]) -> str:
    """The progress bar's note: this iteration's training rollouts (sampled actions) and the last evaluation."""
    text = (f"training rollouts (sampled): SR {row['train_sr']:.2f} Steps {row['train_steps']:.1f} "
            f"CR {row['train_cr']:.2f}")
    last = next((r for r in reversed(rows) if r.get("eval_sr") not in (None, "")), None)
    if last is not None:
        text += f" | evaluation (deterministic) at {last['iteration']}: SR {float(last['eval_sr']):.2f}"
    return text


def checkpoint_iterations(out) -> int | None:
    """Iterations done in the training state of run folder ``out``; ``None`` when there is none yet.

    The state is read in full, as ``resume`` reads it: a file that does not load is a ValueError."""
    path = Path(out) / "state.pt"
    return int(_load_state(path)["iterations"]) if path.exists() else None


def train(scenario: str, cfg: TrainConfig, out, seed: int = 0, resume: bool = False, init=None,
          overrides: dict | None = None, progress: bool = True, command: str | None = None,
          on_iteration=None, method: str = "masp") -> dict:
    """Train ``method`` (``cfg`` from :func:`method_config`); returns the manifest.

    ``on_iteration(trainer)`` runs after every iteration."""
    out = Path(out)
    state_path = out / "state.pt"
    if resume and not state_path.exists():
        raise ValueError(f"--resume: expected a training state at {state_path}, found none")
    if not resume and state_path.exists():
        raise ValueError(f"{state_path} exists; pass --resume to continue it or choose another --out")
    kind = get_scenario(scenario).kind if isinstance(scenario, str) else scenario.kind
    trainer = (DroneMASPTrainer if kind == "drone" else MASPTrainer)(scenario, cfg, seed=seed, overrides=overrides)
    wall_before, rows, started = 0.0, [], datetime.now(timezone.utc).isoformat(timespec="seconds")
    default_command = f"python -m masp_lite train --method {method} --scenario {scenario} --seed {seed}"
    first_command = None
    if resume:
        state = _load_state(state_path)
        saved = dict(state.get("config", {}))
        now = trainer.cfg.flat()  # as the trainer resolved it (an mlp variant's team size)
        defaults = TrainConfig().flat()  # a field added since the state was saved has its default
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
        a, b = (_layout(x.arch) for x in (nets, trainer.nets))
        if a != b:
            raise ValueError(f"--init {init}: architecture {nets.arch} differs from the configured {trainer.nets.arch}")
        trainer.nets.load_state_dict(nets.state_dict())
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    wall = lambda: wall_before + time.perf_counter() - t0  # noqa: E731
    sc = trainer.world.scenario.name

    def save():  # state.pt last: a run stopped between the three files resumes from the previous state
        st = trainer.state_dict()
        st.update(scenario=sc, overrides=dict(overrides or {}), wall_s=wall(), started=started,
                  command=first_command or command or default_command, init=str(init) if init is not None else "")
        _write_csv(out / "progress.csv", rows)
        save_weights(out / "weights.pt", trainer.nets, trainer.world.scenario)
        _save_state(state_path, st)

    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=cfg.run.updates, initial=trainer.iterations, unit="it", desc=f"{method} on {sc}")
    try:
        while trainer.iterations < cfg.run.updates:
            row = trainer.iteration()
            row["wall_s"] = round(wall(), 2)
            if cfg.run.eval_every and trainer.iterations % cfg.run.eval_every == 0:
                ev = evaluate_nets(trainer.nets, sc, overrides, cfg.run.eval_episodes)
                row.update({f"eval_{k}": ev[k] for k in ("sr", "steps", "cr")})
            rows.append({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()})
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(_bar_text(row, rows))
            if trainer.iterations % cfg.run.checkpoint_every == 0 or trainer.iterations == cfg.run.updates:
                save()
            if on_iteration is not None:
                on_iteration(trainer)
    finally:
        if bar is not None:
            bar.close()
    final = evaluate_nets(trainer.nets, sc, overrides, cfg.run.eval_episodes)
    manifest = {
        "method": method, "scenario": sc, "world": trainer.world.scenario.world, "overrides": dict(overrides or {}),
        "seed": int(seed),
        "command": first_command or command or default_command,
        "last_command": command or default_command,
        "init": str(init) if init is not None else None, "config": cfg.flat(),
        "arch": dict(trainer.nets.arch), "iterations": trainer.iterations, "env_steps": trainer.env_steps,
        "wall_clock_s": round(wall(), 1), "started": started,
        "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "torch": torch.__version__,
                    "torch_threads": torch.get_num_threads()},
        "final_eval": {"episodes": cfg.run.eval_episodes, "seed": EVAL_SEED, **final},
        "weights_sha256": sha256(out / "weights.pt"),
    }
    atomic_write_bytes(out / "manifest.json", (json.dumps(manifest, indent=2) + "\n").encode())
    return manifest


_RUN_INFO = ("command", "seed", "init", "iterations", "env_steps", "wall_clock_s", "started", "finished", "machine",
             "config", "final_eval")
_RUN_EXTRA = ("last_command", "overrides", "world", "method")  # absent from older manifests


def _run_info(m: dict) -> dict:
    return {**{k: m[k] for k in _RUN_INFO}, **{k: m[k] for k in _RUN_EXTRA if k in m}}


def _read_run(manifest, progress):
    """``(scenario, run information, curves bytes or None)`` of one finished run."""
    sm = json.loads(Path(manifest).read_text())
    missing = [key for key in _RUN_INFO if key not in sm]
    if missing:
        raise ValueError(f"{manifest}: expected a run manifest; missing {missing}")
    return sm.get("scenario"), _run_info(sm), Path(progress).read_bytes() if Path(progress).exists() else None


def _earlier_runs(earlier):
    """The stages of ``earlier`` (see :func:`ship_run`), oldest first, as :func:`_read_run` gives them."""
    out = []
    for item in earlier:
        if isinstance(item, (str, Path)):  # a kept history: every stage, with its curves
            history = json.loads(Path(item).read_text())
            if "stages" not in history:
                raise ValueError(f"{item}: expected a training history (SCENARIO-seedS.manifest.json)")
            for st in history["stages"]:
                curves = Path(item).parent / st["progress"]
                out.append((st["scenario"], st["training"], curves.read_bytes() if curves.exists() else None))
        else:
            out.append(_read_run(*item))
    return out


def ship_zero_shot(weights_dir, scenario: str, source: str, note: str) -> dict:
    """Ship the weights of the preset ``source`` for the preset ``scenario`` as well, unchanged.

    The size-invariant networks then run zero-shot on ``scenario``: its entry in
    ``weights_dir/manifest.json`` copies ``source``'s (file, hash, history) and adds
    ``"trained_on": source`` and ``note`` (why no weights of its own ship). Returns the entry."""
    manifest_path = Path(weights_dir) / "manifest.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
    if source not in manifest or manifest[source].get("trained_on"):
        raise ValueError(f"ship_zero_shot: expected shipped weights trained on {source!r}; the manifest has "
                         f"{sorted(k for k, v in manifest.items() if not v.get('trained_on'))}")
    manifest[scenario] = _zero_shot_entry(manifest, scenario, source, note)
    _write_json(manifest_path, manifest)
    return manifest[scenario]


def _zero_shot_entry(manifest: dict, scenario: str, source: str, note: str) -> dict:
    return {**manifest[source], "scenario": scenario, "trained_on": source, "note": note}


def _write_json(path, obj) -> None:
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode())


def ship_run(run_dir, history_dir, weights_dir=None, earlier=(), evaluation: dict | None = None,
             note: str | None = None) -> dict:
    """Keep a finished run: its history in ``history_dir``, its weights shipped or beside the history.

    ``history_dir`` (``results/training/``) receives ``SCENARIO-seedS.manifest.json`` —
    every stage's run information (command, configuration, seed, env steps, wall-clock,
    machine, final evaluation) and curves (``SCENARIO-seedS[.stageK].progress.csv``), from
    scratch to the last fine-tuning, plus ``evaluation`` (an ``evaluate()`` record) and a
    free-text ``note``. ``earlier``: the stages this run was fine-tuned from, oldest first,
    each a pair of paths ``(manifest.json, progress.csv)`` of a finished run, or the path of a
    history this function kept before (``SCENARIO-seedS.manifest.json``: all its stages).

    With ``weights_dir`` (the source tree's ``masp_lite/weights/``) the weights become the
    shipped ``SCENARIO.pt`` there, with a slim entry in its ``manifest.json``; without it
    they are kept as ``SCENARIO-seedS.pt`` in ``history_dir`` (training seeds that are not
    shipped). Returns the history manifest.
    """
    run_dir, history_dir = Path(run_dir), Path(history_dir)
    if not (run_dir / "manifest.json").exists():
        raise ValueError(f"{run_dir}: expected a finished run (manifest.json)")
    m = json.loads((run_dir / "manifest.json").read_text())
    rec = read_weights(run_dir / "weights.pt")
    name, seed = rec["scenario"], int(m["seed"])
    stem = f"{name}-seed{seed}"
    runs = [*_earlier_runs(earlier), _read_run(run_dir / "manifest.json", run_dir / "progress.csv")]
    stages = []
    for k, (scenario, info, curves) in enumerate(runs, start=1):
        target = f"{stem}.stage{k}.progress.csv" if k < len(runs) else f"{stem}.progress.csv"
        if curves is not None:
            atomic_write_bytes(history_dir / target, curves)
        stages.append({"scenario": scenario, "training": info, "progress": target})
    data = (run_dir / "weights.pt").read_bytes()
    if weights_dir is None:
        file, target = f"{stem}.pt", history_dir / f"{stem}.pt"
    else:
        file, target = f"{name}.pt", Path(weights_dir) / f"{name}.pt"
    atomic_write_bytes(target, data)
    digest = sha256(target)
    history = {"scenario": name, "world": trained_world(rec), "seed": seed, "file": file, "sha256": digest,
               "arch": rec["arch"],
               "evaluation": evaluation, "note": note, "stages": stages}
    _write_json(history_dir / f"{stem}.manifest.json", history)
    if weights_dir is not None:
        manifest_path = Path(weights_dir) / "manifest.json"
        manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
        runs = [st["training"] for st in stages]
        manifest[name] = {"file": file, "sha256": digest, "scenario": name, "world": trained_world(rec),
                          "arch": rec["arch"], "seed": seed,
                          "command": runs[-1]["command"], "stages": len(runs),
                          "env_steps": sum(r["env_steps"] for r in runs),
                          "wall_clock_s": round(sum(r["wall_clock_s"] for r in runs), 1),
                          "machine": runs[-1]["machine"], "history": f"results/training/{stem}.manifest.json"}
        for other, entry in manifest.items():  # presets that ship these weights zero-shot follow them
            if entry.get("trained_on") == name:
                manifest[other] = _zero_shot_entry(manifest, other, name, entry["note"])
        _write_json(manifest_path, manifest)
    return history
