"""Training runs: a folder that survives being killed, and a manifest.

:func:`train` runs MASP (:class:`~masp_lite.algos.masp_trainer.MASPTrainer`) and writes, in
its run folder (``python -m masp_lite train`` defaults to ``runs/masp-SCENARIO-seedS``):

* ``state.pt`` — the full training state (weights, optimizers, value norms, every RNG
  state), saved atomically (temporary file + ``os.replace``) every ``checkpoint_every``
  iterations, after the two files below, so that a run stopped at any moment (Ctrl-C,
  a kill) leaves a whole state that agrees with them; ``--resume`` continues from it and
  ends with exactly the parameters an uninterrupted run would have (the RNG states make
  the rest of the run identical);
* ``weights.pt`` — the latest networks in the shipped format (:mod:`masp_lite.weights`);
* ``progress.csv`` — one row per iteration: env steps, wall-clock, training SR/Steps/CR
  (measured as :mod:`masp_lite.evaluation.metrics` defines them, on the training episodes),
  mean rewards, losses and entropies of both levels, the periodic evaluation
  (deterministic policies, ``eval_episodes`` episodes, fixed evaluation seed), and PPO's
  health per level (approximate KL, clip fraction, explained variance:
  :data:`~masp_lite.algos.mappo.HEALTH`);
* ``manifest.json`` — the first command, the last one (a resume), seed, configuration, env
  steps, wall-clock (summed over resumes), machine and the final evaluation. A run can be
  ended early by resuming it with ``--set updates=N`` (N = iterations done): nothing in the
  schedule depends on ``updates``, so the manifest's configuration then reproduces it.

The configuration is a :class:`~masp_lite.config.TrainConfig`. ``init`` starts from a
weights file of the same architecture (fine-tuning, e.g. mpe-50 from the mpe-20 weights).
Refused with one clear error, nothing overwritten: ``resume`` without ``state.pt``; an
existing ``state.pt`` without ``resume``; a corrupt state; a state trained with another
scenario or configuration (only ``updates`` may grow on resume).

Keeping a finished run in a source checkout (its weights shipped, its history kept) is the
reproduction room's (:mod:`masp_lite.reproduction.shipping`).
"""
from __future__ import annotations

import csv
import io
import json
import os
import platform
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import torch

from .algos.mappo import HEALTH, NonFiniteError
from .algos.masp_trainer import MASPTrainer
from .config import TrainConfig
from .envs import OVERRIDES, Scenario, get_scenario, make, world_name
from .evaluation import collision_rate, rollout, steps, success_rate
from .evaluation.evaluate import check_memory
from .files import TMP_PREFIX, atomic_write, read_bounded, sha256
from .parsing import field_types, parse_sets
from .policies import get_factory, learned_methods
from .weights import load_weights, save_weights, trained_world

__all__ = ["train", "parse_config", "parse_settings", "method_config", "evaluate_nets", "checkpoint_iterations",
           "trainer_class", "CSV_FIELDS", "EVAL_SEED", "RunWriteError", "RUN_MARK"]

CSV_FIELDS = ["iteration", "env_steps", "wall_s", "train_sr", "train_steps", "train_cr", "gm_reward", "cae_reward",
              "gm_policy_loss", "gm_value_loss", "gm_entropy", "cae_policy_loss", "cae_value_loss", "cae_entropy",
              "eval_sr", "eval_steps", "eval_cr",
              *(f"{level}_{k}" for level in ("gm", "cae") for k in HEALTH)]
"""``progress.csv``'s columns. PPO's health (:data:`~masp_lite.algos.mappo.HEALTH`) came last, in 2026-12:
files written before have none of those columns, and every reader takes a file without them."""
EVAL_SEED = 12_345
#: The empty file that marks a folder as a run of :func:`train`: a fresh run writes only into a new or
#: empty folder, or one holding this mark (its own earlier run, stopped before its first checkpoint).
RUN_MARK = ".masp-run"
#: The largest training state read (a run's state.pt is well under a megabyte for the paper's networks).
MAX_STATE_BYTES = 256 * 2**20


class RunWriteError(ValueError):
    """The run folder could not be written during training (disk full, read-only): the last checkpoint is whole.

    ``last_checkpoint``: the iterations in that checkpoint, ``None`` when none was written yet."""

    last_checkpoint: int | None = None


def method_config(method: str | None, sets=(), scenario: str | Scenario | None = None) -> tuple[str, TrainConfig, dict]:
    """``(method, config, scenario overrides)`` of ``train [--method METHOD] --set ...``.

    The configuration is the method's settings for the scenario's world kind (its ``nets`` and
    ``train`` in the method table, :data:`masp_lite.policies.METHODS`), then ``sets`` (parsed once,
    :func:`parse_settings`). Without a method, the first one whose settings ``sets`` give is meant (``--set
    goal_matcher=random`` is ``masp-rg``, as the ablations' manifests were written; on drones
    ``--set action=velocity`` is ``masp-velocity``), MASP by default. One clear error for a
    method that is not trained for the world kind, or a ``--set`` that would make it another method.
    """
    kind = get_scenario(scenario).kind if scenario is not None else "particle"
    table = learned_methods(kind)
    given, overrides = parse_settings(sets)
    if kind == "particle" and "action" in given:
        raise ValueError("train: --set action is for drone scenarios (drone-*); particle networks take MPE's "
                         "discrete actions")
    method = _implied_method(table, kind, given) if method is None else method
    if method not in table:
        raise ValueError(f"train: {method!r} is not a method trained on {kind} worlds; expected one of "
                         f"{sorted(table)}")
    own = {**table[method]["nets"], **table[method].get("train", {})}
    cfg = TrainConfig.from_flat({**own, **given})
    for k in table[method]["nets"]:
        if getattr(cfg.net, k) != own[k]:
            raise ValueError(f"train --method {method}: {k} is {own[k]!r} for this method; --set {k}="
                             f"{getattr(cfg.net, k)} makes another one (see masp_lite.policies.METHODS)")
    return method, cfg, overrides


def _implied_method(table: dict, kind: str, given: dict) -> str:
    """The first method of ``table`` whose network settings the ``--set`` values ``given`` make (on the
    world kind's defaults: MASP's settings on particles, throttle actions on drones)."""
    base = table["masp"]["nets"] if kind == "particle" else {"action": "throttle"}
    cfg = TrainConfig.from_flat({**base, **given})
    match = [m for m, e in table.items() if all(getattr(cfg.net, k) == x for k, x in e["nets"].items())]
    if not match:
        got = {k: getattr(cfg.net, k) for k in ("goal_matcher", "executor", "action")}
        raise ValueError(f"train: no {kind} method has the settings {got}; expected one of "
                         + "; ".join(f"{m} {e['nets']}" for m, e in table.items()))
    return match[0]


def _layout(arch: dict) -> dict:
    """The settings that decide the networks' parameters: a stage may change the others (the Goal
    Matcher's period; Hungarian or random goals to a trained Goal Matcher, whose networks exist in
    every weights file) and start from the weights of the stage before (``--init``)."""
    same_networks = {"graph": "graph", "hungarian": "graph", "random": "graph"}
    out = {k: v for k, v in arch.items() if k != "global_step"}
    out["goal_matcher"] = same_networks.get(arch["goal_matcher"], arch["goal_matcher"])
    return out


def parse_settings(sets) -> tuple[dict, dict]:
    """``KEY=VALUE`` strings -> (training settings, scenario overrides), each value of its field's type: the one
    parse of ``train``'s ``--set`` (:func:`masp_lite.parsing.parse_sets`)."""
    got = parse_sets(sets, {"training setting": field_types(TrainConfig), "scenario override": OVERRIDES})
    return got["training setting"], got["scenario override"]


def parse_config(sets) -> tuple[TrainConfig, dict]:
    """``KEY=VALUE`` strings -> (TrainConfig, scenario overrides), by :func:`parse_settings`."""
    settings, overrides = parse_settings(sets)
    return TrainConfig.from_flat(settings), overrides


def evaluate_nets(nets, scenario, overrides=None, episodes: int = 32, seed: int = EVAL_SEED) -> dict:
    """SR, Steps and CR of the deterministic policies over ``episodes`` episodes (means)."""
    world = make(scenario, num_envs=min(episodes, 100), seed=seed, **(overrides or {}))
    was = nets.training
    nets.eval()
    cls = get_factory("masp", nets.config.world).func  # the learned policy class of the world's kind
    log, dt = rollout(world, cls.from_nets(world, nets, seed=seed), episodes, seed)
    nets.train(was)
    return {"sr": float(success_rate(log).mean()), "steps": float(steps(log).mean()),
            "cr": float(collision_rate(log).mean()), "decision_ms": dt * 1e3}


def _save_state(path: Path, state: dict) -> None:
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write(path, buf.getvalue())


def _load_state(path: Path) -> dict:
    data = read_bounded(path, MAX_STATE_BYTES, "training state")
    try:
        state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as e:
        raise ValueError(f"{path}: expected a training state saved by 'train', could not read it "
                         f"({type(e).__name__})") from None
    _check_state_fields(path, state)
    try:
        _check_finite(_tensors(state), "value")
    except NonFiniteError as e:
        raise ValueError(f"{path}: expected a training state with finite values; {e}") from None
    return state


#: The fields of a training state that are read before the trainer loads it, with their types.
_STATE_FIELDS = {"nets": dict, "gm_opt": dict, "cae_opt": dict, "gm_norm": dict, "cae_norm": dict,
                 "generator": torch.Tensor, "iterations": int, "env_steps": int, "config": dict, "seed": int,
                 "wall_s": (int, float), "started": str}


def _check_state_fields(path: Path, state) -> None:
    """One clear error naming the field of a training state that is missing, mistyped or negative."""
    if not isinstance(state, dict):
        raise ValueError(f"{path}: expected a training state (a dict) saved by 'train', got a {type(state).__name__}")
    for key, typ in _STATE_FIELDS.items():
        v = state.get(key)
        if key not in state or not isinstance(v, typ) or isinstance(v, bool):
            got = "missing" if key not in state else f"a {type(v).__name__}"
            raise ValueError(f"{path}: field {key!r} is {got}; expected a training state saved by 'train'")
    for key in ("iterations", "env_steps", "seed", "wall_s"):
        if state[key] < 0 or (key == "wall_s" and not float(state[key]) < float("inf")):
            raise ValueError(f"{path}: field {key!r} is {state[key]!r}; expected a count >= 0")
    for key in ("overrides",):
        if not isinstance(state.get(key, {}), dict):
            raise ValueError(f"{path}: field {key!r} is a {type(state[key]).__name__}; expected a dict")


def _optimizer_settings(trainer) -> dict:
    """``{"OPTIMIZER.GROUP.SETTING": value}`` of the settings that shape each step (learning rate, betas, eps,
    weight decay): a state keeps its own, so one whose optimizer says ``lr`` 10 would train on with it."""
    return {f"{name}.{i}.{k}": g[k] for name, opt in vars(trainer).items() if isinstance(opt, torch.optim.Optimizer)
            for i, g in enumerate(opt.param_groups) for k in ("lr", "betas", "eps", "weight_decay") if k in g}


def _check_out(out: Path) -> None:
    """A fresh run writes into a new or empty folder, or its own earlier run (:data:`RUN_MARK`); never
    into a folder of other files (a user's manifest, a shipped weights folder), which it would replace."""
    if not out.is_dir() or (out / RUN_MARK).exists():
        return
    others = sorted(p.name for p in out.iterdir() if p.name != ".lock" and not p.name.startswith(TMP_PREFIX))
    if others:
        raise ValueError(f"--out {out}: the folder holds other files ({', '.join(others[:5])}"
                         f"{', ...' if len(others) > 5 else ''}) that a run would replace; expected a new or empty "
                         "folder, or a run folder of train (--resume continues one)")


def _check_run_files(out: Path) -> None:
    """Each file a run writes is a regular file or absent: a folder in its place is refused before training."""
    for name in ("state.pt", "weights.pt", "progress.csv", "manifest.json"):
        path = out / name
        if path.exists() and not path.is_file():
            raise ValueError(f"{path} is a folder or another non-file; expected the run's {name} there or nothing "
                             "(move it away, then run again)")


def _tensors(tree, prefix=""):
    """(name, tensor) of every floating-point tensor in a nested dict/list, names joined by '.'."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, (list, tuple)) else ()
    for k, v in items:
        name = f"{prefix}{k}"
        if isinstance(v, torch.Tensor):
            if v.is_floating_point():
                yield name, v
        else:
            yield from _tensors(v, name + ".")


def _check_finite(named, what: str) -> None:
    """Raise :class:`NonFiniteError` naming the first of ``named`` (name, tensor) that holds a NaN or inf."""
    for name, t in named:
        if not torch.isfinite(t).all():
            raise NonFiniteError(f"{what} {name} is not finite")


def _take_lock(out: Path) -> Path:
    """Create run folder ``out`` and hold its lock (``out/.lock``, this process's PID) for one run.

    A second run into the same folder is refused naming the holder; a lock left by a process
    that no longer runs (``kill -9``) is taken over. A folder that cannot be written is one
    clear error."""
    lock = out / ".lock"
    try:
        out.mkdir(parents=True, exist_ok=True)
        for _ in range(2):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                holder = _lock_holder(lock)
                if holder is not None:
                    raise ValueError(f"{out} is being trained by process {holder} (lock {lock}); wait for it to "
                                     f"finish or choose another --out") from None
                lock.unlink(missing_ok=True)  # stale: its process is gone
                continue
            with os.fdopen(fd, "w") as f:
                f.write(f"{os.getpid()}\n")
            return lock
    except OSError as e:
        raise ValueError(f"--out {out}: expected a folder that can be written, could not write there "
                         f"({e.strerror or type(e).__name__})") from None
    raise ValueError(f"{out}: could not take the run's lock {lock}; another run is starting there")


def _lock_holder(lock: Path) -> int | None:
    """The PID in a run lock if that process still runs, else ``None``."""
    try:
        pid = int(read_bounded(lock, 64, "run lock").split()[0])
        os.kill(pid, 0)
    except PermissionError:  # it runs, as another user
        return pid
    except (OSError, ValueError, IndexError):
        return None
    return pid


def _release_lock(lock: Path) -> None:
    if _lock_holder(lock) == os.getpid():
        lock.unlink(missing_ok=True)


def _write(run: _Run, write) -> None:
    """Run ``write()``; a full disk or a read-only folder becomes one :class:`RunWriteError` naming the folder
    and the last whole checkpoint (every file is written atomically, so the one before stays intact)."""
    try:
        write()
    except OSError as e:
        try:
            last = checkpoint_iterations(run.out)
        except ValueError:
            last = None
        kept = f"the last checkpoint ({run.state_path}, iteration {last}) is intact" if last is not None \
            else "no checkpoint was written yet"
        err = RunWriteError(f"training stopped at iteration {run.trainer.iterations}: could not write the run folder "
                            f"{run.out} ({e.strerror or type(e).__name__}); {kept}")
        err.last_checkpoint = last
        raise err from None


def _write_csv(path: Path, rows: list[dict]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    atomic_write(path, buf.getvalue())


def _read_csv(path: Path, upto: int) -> list[dict]:
    """The history of iterations 1..``upto`` from a run's ``progress.csv``; a missing or garbled file is an error."""
    if upto == 0:
        return []
    what = f"{path}: expected the history of the {upto} iterations in the training state"
    if not path.exists():
        raise ValueError(f"{what}; the file is missing (resuming would lose the curve)")
    try:
        text = read_bounded(path, MAX_STATE_BYTES, "training history").decode()
        rows = [r for r in csv.DictReader(io.StringIO(text, newline="")) if int(r["iteration"]) <= upto]
    except (KeyError, ValueError, TypeError, UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{what}; could not read it ({type(e).__name__}: {e})") from None
    if [int(r["iteration"]) for r in rows] != list(range(1, upto + 1)):
        raise ValueError(f"{what}; it holds iterations {[r['iteration'] for r in rows][:5]}...")
    return rows


def _bar_text(row: dict, rows: list[dict]) -> str:
    """The progress bar's note: this iteration's training rollouts (sampled actions) and the last evaluation."""
    text = (f"training rollouts (sampled): SR {row['train_sr']:.2f} Steps {row['train_steps']:.1f} "
            f"CR {row['train_cr']:.2f}")
    last = next((r for r in reversed(rows) if r.get("eval_sr") not in (None, "")), None)
    if last is not None:
        text += f" | evaluation (deterministic) at {last['iteration']}: SR {float(last['eval_sr']):.2f}"
    return text


def trainer_class(kind: str, cfg: TrainConfig | None = None) -> type[MASPTrainer]:
    """The trainer of a world kind: :class:`MASPTrainer`, or for drones its subclass (MuJoCo only then); with
    ``cfg``'s ``imitate`` set, the imitation stage's (:class:`~masp_lite.algos.imitation.ImitationTrainer`,
    particle worlds)."""
    if cfg is not None and cfg.imitation.imitate != "none":
        if kind != "particle":
            raise ValueError(f"imitate: the imitation stage is for particle worlds; this scenario is a {kind} "
                             "world (expected --set imitate=none)")
        from .algos.imitation import ImitationTrainer
        return ImitationTrainer
    if kind == "drone":
        from .algos.drone_trainer import DroneMASPTrainer
        return DroneMASPTrainer
    return MASPTrainer


def checkpoint_iterations(out) -> int | None:
    """Iterations done in the training state of run folder ``out``; ``None`` when there is none yet.

    The state is read in full, as ``resume`` reads it: a file that does not load is a ValueError."""
    path = Path(out) / "state.pt"
    return int(_load_state(path)["iterations"]) if path.exists() else None


def train(scenario: str | Scenario, cfg: TrainConfig, out, seed: int = 0, resume: bool = False, init=None,
          overrides: dict | None = None, progress: bool = True, command: str | None = None,
          on_iteration=None, method: str = "masp", trainer_type: type[MASPTrainer] | None = None) -> dict:
    """Train ``method`` (``cfg`` from :func:`method_config`) on ``scenario`` (a preset name or a
    :class:`~masp_lite.envs.Scenario`) with ``overrides``; returns the manifest.

    The scenario is built once, here, and every part of the run (trainer, evaluations, weights) gets
    it. ``on_iteration(trainer)`` runs after every iteration. ``trainer_type``: a subclass of the
    world kind's trainer (:func:`trainer_class`) that changes one part of training for a
    research question (``experiments/``): its goal draw, its reward or its networks, passed
    as an argument instead of patching the library. What it changes is not stored in the run:
    resume with the same one."""
    out, overrides = Path(out), dict(overrides or {})
    _check_start(out, resume)
    sc = get_scenario(scenario, **overrides)
    cls = _trainer_type(sc.kind, trainer_type, cfg)
    check_memory(sc.num_agents, cfg.run.num_envs, "--set num_envs=")  # before any world or network is built
    given = command or f"python -m masp_lite train --method {method} --scenario {sc.name} --seed {seed}"
    run = _Run(out, cls(sc, cfg, seed=seed), method, int(seed), overrides, command=given, last_command=given,
               init=init)
    if resume:
        _resume(run, cfg)
    elif init is not None:
        _start_from(run.trainer, init, overrides)
    lock = _take_lock(out)
    try:
        _write(run, lambda: atomic_write(out / RUN_MARK, b""))
        run.t0 = time.perf_counter()
        _loop(run, cfg, progress, on_iteration)
        return _finish(run, cfg)
    finally:
        _release_lock(lock)


@dataclass
class _Run:
    """One training run: its folder, its trainer and what its checkpoints and manifest record."""

    out: Path
    trainer: MASPTrainer
    method: str
    seed: int
    overrides: dict
    command: str
    """The run's first command (a resume keeps it)."""
    last_command: str
    """The command that started this part of the run (the last resume's, or the first)."""
    init: str | Path | None = None
    """The weights the run started from (``--init``)."""
    started: str = field(default_factory=lambda: datetime.now(timezone.utc).isoformat(timespec="seconds"))
    wall_before: float = 0.0
    """Wall-clock seconds the run took before this resume."""
    rows: list = field(default_factory=list)
    """``progress.csv``'s rows so far."""
    t0: float = field(default_factory=time.perf_counter)

    @property
    def state_path(self) -> Path:
        return self.out / "state.pt"

    def wall(self) -> float:
        """Wall-clock seconds of the whole run, resumes summed."""
        return self.wall_before + time.perf_counter() - self.t0


def _check_start(out: Path, resume: bool) -> None:
    """``resume`` needs a training state in ``out``; a fresh run needs none, and a folder it may write
    (:func:`_check_out`); either way each of the run's files is a file or absent."""
    state_path = out / "state.pt"
    if resume and not state_path.exists():
        raise ValueError(f"--resume: expected a training state at {state_path}, found none")
    if not resume and state_path.exists():
        raise ValueError(f"{state_path} exists; pass --resume to continue it or choose another --out")
    if not resume:
        _check_out(out)
    _check_run_files(out)


def _trainer_type(kind: str, trainer_type, cfg: TrainConfig) -> type[MASPTrainer]:
    """The world kind's trainer (:func:`trainer_class`), or ``trainer_type`` when it is a subclass of it."""
    base = trainer_class(kind, cfg)
    if trainer_type is not None and not (isinstance(trainer_type, type) and issubclass(trainer_type, base)):
        raise ValueError(f"trainer_type: expected a subclass of {base.__name__} (the {kind} trainer), "
                         f"got {trainer_type!r}")
    return trainer_type or base


def _resume(run: _Run, cfg: TrainConfig) -> None:
    """Continue ``run`` from its training state, once the state is shown to be this run's (:func:`_check_same_run`):
    the trainer's state, the wall-clock so far, the first command, ``--init`` and the history."""
    state = _load_state(run.state_path)
    _check_same_run(run, cfg, state)
    _load_trainer_state(run.trainer, state, run.state_path)
    run.wall_before, run.started = float(state["wall_s"]), state["started"]
    run.command = state.get("command") or run.command
    run.init = state.get("init") or run.init
    run.rows = _read_csv(run.out / "progress.csv", run.trainer.iterations)


def _check_same_run(run: _Run, cfg: TrainConfig, state: dict) -> None:
    """A state of the same scenario, overrides, seed and settings (only ``updates`` may grow), that many
    iterations at most; one clear error naming what differs."""
    path, trainer = run.state_path, run.trainer
    saved = dict(state.get("config", {}))
    now = trainer.cfg.flat()  # as the trainer resolved it (an mlp variant's team size)
    defaults = TrainConfig().flat()  # a field added since the state was saved has its default
    diff = sorted(k for k in now if k != "updates" and saved.get(k, defaults[k]) != now[k])
    if state.get("scenario") != trainer.world.scenario.name or state.get("overrides", {}) != run.overrides:
        raise ValueError(f"{path} was trained on {state.get('scenario')!r} {state.get('overrides')}; "
                         f"expected {trainer.world.scenario.name!r} {run.overrides}")
    if diff or int(state.get("seed", -1)) != run.seed:
        sides = [f"{k}: run {saved.get(k, defaults[k])!r}, now {now[k]!r}" for k in diff] or \
            [f"seed: run {state.get('seed')!r}, now {run.seed!r}"]
        raise ValueError(f"{path}: expected the same seed and settings as the interrupted run; "
                         f"differs in {[*diff] or ['seed']} ({'; '.join(sides)})")
    if cfg.run.updates < int(state["iterations"]):
        raise ValueError(f"--set updates={cfg.run.updates}: expected at least the {state['iterations']} iterations "
                         f"already done in {path} (updates={state['iterations']} ends the run there)")


def _load_trainer_state(trainer: MASPTrainer, state: dict, path: Path) -> None:
    """Load ``state`` into ``trainer``: it must fit the networks, keep the configuration's optimizer settings
    and have been trained on as many torch threads as now (another count sums in another order)."""
    fresh = _optimizer_settings(trainer)
    try:
        trainer.load_state_dict(state)
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError) as e:
        raise ValueError(f"{path}: expected a training state of these networks, could not load it "
                         f"({type(e).__name__}: {str(e).splitlines()[0][:200] if str(e) else 'no message'})") \
            from None
    loaded = _optimizer_settings(trainer)
    if loaded != fresh:
        k = next(k for k in fresh if loaded.get(k) != fresh[k])
        raise ValueError(f"{path}: its optimizer setting {k} is {loaded.get(k)!r}, the configuration's is "
                         f"{fresh[k]!r}; expected a training state saved by 'train' with these settings")
    if isinstance(state.get("threads"), int) and state["threads"] != torch.get_num_threads():
        raise ValueError(f"{path} was trained with {state['threads']} torch thread(s), now "
                         f"{torch.get_num_threads()}; resume with --threads {state['threads']} (other threads "
                         "sum in another order and give other weights)")


def _start_from(trainer: MASPTrainer, init, overrides: dict) -> None:
    """``--init``: the networks start from a weights file of the same layout (:func:`_layout`), trained in this
    run's world unless the overrides name the world (moving weights between worlds on purpose)."""
    nets, rec = load_weights(init, any_scenario=True)
    a, b = (_layout(x.arch) for x in (nets, trainer.nets))
    if a != b:
        differ = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        sides = "; ".join(f"{k}: --init {a.get(k)!r}, configured {b.get(k)!r}" for k in differ)
        hint = " (an mlp variant is built for one team size: fine-tune it at the same N)" \
            if "team_size" in differ else ""
        raise ValueError(f"--init {init}: architecture differs from the configured networks in {sides}{hint}")
    came_from, world = trained_world(rec), trainer.world.scenario.world
    if came_from != world and not set(world) & set(overrides):
        raise ValueError(f"--init {init}: trained in the world {world_name(came_from)}, this run's is "
                         f"{world_name(world)}; to move weights between worlds on purpose, name the world "
                         f"(--set " + " --set ".join(f"{k}={v}" for k, v in world.items()) + ")")
    trainer.nets.load_state_dict(nets.state_dict())


def _loop(run: _Run, cfg: TrainConfig, progress: bool, on_iteration) -> None:
    """Iterate until ``updates``: each iteration's row (with the periodic evaluation) goes to the history, a
    checkpoint every ``checkpoint_every`` iterations and at the end."""
    trainer = run.trainer
    bar = _progress_bar(run, cfg) if progress else None
    try:
        while trainer.iterations < cfg.run.updates:
            row = _iterate(run)
            row["wall_s"] = round(run.wall(), 2)
            if cfg.run.eval_every and trainer.iterations % cfg.run.eval_every == 0:
                ev = evaluate_nets(trainer.nets, trainer.world.scenario, episodes=cfg.run.eval_episodes)
                row.update({f"eval_{k}": ev[k] for k in ("sr", "steps", "cr")})
            run.rows.append({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()})
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(_bar_text(row, run.rows))
            if trainer.iterations % cfg.run.checkpoint_every == 0 or trainer.iterations == cfg.run.updates:
                _save(run)
            if on_iteration is not None:
                on_iteration(trainer)
    finally:
        if bar is not None:
            bar.close()


def _progress_bar(run: _Run, cfg: TrainConfig):
    from tqdm import tqdm
    return tqdm(total=cfg.run.updates, initial=run.trainer.iterations, unit="it",
                desc=f"{run.method} on {run.trainer.world.scenario.name}")


def _iterate(run: _Run) -> dict:
    """One iteration, its parameters checked finite after it: a NaN or inf stops the run with one error that
    says what was kept (nothing of the failed iteration is written)."""
    try:
        row = run.trainer.iteration()
        _check_finite(run.trainer.nets.named_parameters(), "parameter")
    except NonFiniteError as e:
        last = checkpoint_iterations(run.out)
        kept = f"the last checkpoint ({run.state_path}, iteration {last}) is intact" if last is not None \
            else "no checkpoint was written"
        raise NonFiniteError(f"training stopped at iteration {run.trainer.iterations + 1}: {e}; nothing was "
                             f"written, {kept}") from None
    return row


def _save(run: _Run) -> None:
    """A checkpoint: the history, the weights, then the training state (last: a run stopped between the files
    resumes from the previous state). A finished run's manifest, resumed, is removed (its hash goes stale)."""
    trainer, out = run.trainer, run.out
    st = trainer.state_dict()
    st.update(scenario=trainer.world.scenario.name, overrides=dict(run.overrides), wall_s=run.wall(),
              started=run.started, command=run.command, init=str(run.init) if run.init is not None else "",
              threads=torch.get_num_threads())
    _write(run, lambda: (
        _write_csv(out / "progress.csv", run.rows),
        (out / "manifest.json").unlink(missing_ok=True),
        save_weights(out / "weights.pt", trainer.nets, trainer.world.scenario),
        _save_state(run.state_path, st)))


def _finish(run: _Run, cfg: TrainConfig) -> dict:
    """The final evaluation and the manifest (written last: a run folder with a manifest is finished)."""
    trainer = run.trainer
    final = evaluate_nets(trainer.nets, trainer.world.scenario, episodes=cfg.run.eval_episodes)
    manifest = {
        "method": run.method, "scenario": trainer.world.scenario.name, "world": trainer.world.scenario.world,
        "overrides": dict(run.overrides), "seed": run.seed, "command": run.command, "last_command": run.last_command,
        "init": str(run.init) if run.init is not None else None, "config": cfg.flat(),
        "arch": dict(trainer.nets.arch), "iterations": trainer.iterations, "env_steps": trainer.env_steps,
        "wall_clock_s": round(run.wall(), 1), "started": run.started,
        "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "torch": torch.__version__,
                    "torch_threads": torch.get_num_threads()},
        "final_eval": {"episodes": cfg.run.eval_episodes, "seed": EVAL_SEED, **final},
        "weights_sha256": sha256(run.out / "weights.pt"),
    }
    text = json.dumps(manifest, indent=2) + "\n"
    _write(run, lambda: atomic_write(run.out / "manifest.json", text))
    return manifest
