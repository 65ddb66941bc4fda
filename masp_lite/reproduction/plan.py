"""The plan of ``reproduce --train``: every kept weights file, retrained from its recipe.

The plan is built from the recipes (:mod:`masp_lite.recipes`): for every recipe, training seed
0, 1 and 2, and every stage whose weights are kept (``Stage.keep``), one :class:`Run` — that
stage and the ones it starts from. The kept histories (``results/training/**/NAME-seedK.manifest.json``,
written by :func:`masp_lite.reproduction.shipping.ship_run`) are the record of what ran: a run
whose history matches its recipe stage by stage (scenario, overrides, every setting) shows the
environment steps and wall-clock measured when it was trained; one that does not match (or has
no history yet) is planned all the same, its wall-clock unknown. The records a run re-makes are
every record in ``results/`` whose checkpoint is the run's weights file, or, for shipped weights
and a method's packaged seed-0 copy (refreshed with the run), the records that read them by default.
A kept history that no recipe makes is left out with the reason (:func:`read_plan`'s second list).

:func:`run_plan` trains each stage in ``runs/reproduce/stages/`` under a name that hashes
the stage and everything it starts from, so two runs that share their first stages
(drone-20 starts from drone-5's, mpe-5 from mpe-20's) train them once. A stage folder is a
:func:`masp_lite.training.train` run folder: a killed plan resumes every stage from its
last checkpoint and skips finished ones. A finished run's weights and history are shipped
where the single-machine commands keep them (``results/training/...`` or
``masp_lite/weights/``), then its records are re-made in place. Runs that share a stage
form one task; tasks run in turn, or as Ray tasks (``ray`` installed: a local Ray on this
machine's cores, or ``address`` of a running cluster whose workers see ``root`` and
have this package installed), one task per worker with the stages' own thread counts. The
same seeds give the same weights either way (tested).

Why Ray: it is the ecosystem's way to spread independent Python jobs over cores and machines
with resource requests (``num_cpus``) and no code of our own for workers or queues.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from ..config import TrainConfig
from ..envs import get_scenario
from ..evaluation import evaluate
from ..files import atomic_write, read_bounded, sha256
from ..recipes import RECIPES, Recipe, stage_config
from ..training import train
from ..weights import base_scenario, packaged_preset, trained_preset
from .reproduce import load_records
from .shipping import ship_run

__all__ = ["Stage", "Run", "read_plan", "load_plan", "save_plan", "describe", "run_plan", "STAGES_DIR",
           "RAY_INSTALL"]

STAGES_DIR = "runs/reproduce/stages"
"""Where the stages train, relative to the root (one resumable run folder each)."""
RAY_INSTALL = ".venv/bin/pip install 'ray==2.60.0'   (or pip install '.[ray]')"


@dataclass(frozen=True)
class Stage:
    """One training stage: :func:`masp_lite.training.train` with these arguments."""

    scenario: str
    method: str
    seed: int
    config: dict
    """The flat :class:`~masp_lite.config.TrainConfig`."""
    overrides: dict
    init: int | None
    """Index (in the run) of the stage whose weights this one starts from; None: random networks."""
    threads: int
    env_steps: int
    wall_clock_s: float | None
    """As measured when the kept run was trained (its manifest); ``None`` when no kept run matches the recipe."""


@dataclass(frozen=True)
class Run:
    """One kept history, retrained: its stages, where its weights go, the records made from them."""

    name: str
    """The history's path under ``results/training/`` without ``.manifest.json``, e.g. ``mappo/mpe-50-seed0``."""
    stages: tuple
    shipped: bool
    """Whether the weights ship in ``masp_lite/weights/`` (else they are kept beside the history)."""
    note: str | None
    records: tuple
    """Record paths relative to the root, re-made from the weights."""
    packaged: str | None = None
    """The package's copy of these weights (``masp_lite/weights/methods/METHOD/PRESET.pt``, a learned method's
    seed-0 default), refreshed when the run is shipped; None when the package holds none."""

    @property
    def env_steps(self) -> int:
        return sum(s.env_steps for s in self.stages)

    @property
    def wall_clock_s(self) -> float | None:
        """Summed over the stages; ``None`` when a stage has not been run from its recipe yet."""
        times = [s.wall_clock_s for s in self.stages]
        return None if None in times else sum(times)


SEEDS = (0, 1, 2)
"""The training seeds every kept run is trained with (the tables pool them)."""


def _kept_stages(history: dict | None, planned: list) -> list | None:
    """The kept history's stages when they are the recipe's (scenario, overrides, every setting), else None."""
    if history is None or len(history.get("stages", ())) != len(planned):
        return None
    defaults = TrainConfig().flat()  # a setting added since a stage was trained had its default then
    out = []
    try:
        for st, p in zip(history["stages"], planned):
            t = st["training"]
            if st["scenario"] != p.scenario or dict(t.get("overrides", {})) != p.overrides or \
                    {**defaults, **t["config"]} != p.config or int(t["seed"]) != p.seed:
                return None
            out.append({**t, "wall_clock_s": float(t["wall_clock_s"]), "env_steps": int(t["env_steps"]),
                        "torch_threads": int((t.get("machine") or {}).get("torch_threads", 1))})
    except (KeyError, TypeError, ValueError, AttributeError):  # a malformed stage: not a record of this recipe
        return None
    return out


def _run_stages(recipe: Recipe, keep_stage, seed: int, history: dict | None) -> tuple:
    """The plan's stages of one recipe run (the chain ending at ``keep_stage``), timed by its kept history."""
    chain = recipe.chain(keep_stage.name)
    planned = []
    for k, st in enumerate(chain):
        method, cfg, overrides = stage_config(recipe, st)
        init = None if st.start is None else [c.name for c in chain].index(st.start)
        steps = st.iterations * st.worlds * get_scenario(st.scenario, **overrides).horizon
        planned.append(Stage(st.scenario, method, seed, cfg.flat(), overrides, init, 1, steps, None))
    kept = _kept_stages(history, planned)
    if kept is None:
        return tuple(planned)
    return tuple(Stage(**{**asdict(p), "threads": t["torch_threads"], "env_steps": t["env_steps"],
                          "wall_clock_s": t["wall_clock_s"]})
                 for p, t in zip(planned, kept))


METHODS_MANIFEST = "masp_lite/weights/methods/manifest.json"
"""The package's seed-0 weights of the learned methods besides the shipped MASP, relative to the root."""


def _packaged(root: Path) -> dict:
    """``{weights file the package copies: (method, preset, package file, the method's packaged presets)}``,
    paths relative to ``root``."""
    path = root / METHODS_MANIFEST
    data = json.loads(read_bounded(path, what="manifest")) if path.exists() else {}
    return {e["copy_of"]: (m, p, str(Path(METHODS_MANIFEST).parent / e["file"]), tuple(presets))
            for m, presets in data.items() for p, e in presets.items()}


def _records(records, root: Path, name: str, shipped_preset: str | None, packaged=None) -> tuple:
    """The records (from :func:`masp_lite.evaluation.load_records`) made from this run's weights, as paths
    relative to ``root``: those whose checkpoint is the run's file, and those that read the weights a run's
    file is the default of (no checkpoint): the shipped MASP of a preset (``shipped_preset``), or a method's
    packaged copy (``packaged``: an entry of :func:`_packaged`), as the method itself or as a planner's goal
    source (``goals=METHOD``). Bench timings, which have no ``seeds``, are not re-made."""
    target = f"results/training/{name}.pt"
    out = []
    for rec in records:
        opts = rec.get("method_options", {})
        reads = opts.get("goals", rec["method"])  # the method whose weights the record runs
        if "checkpoint" in opts:
            mine = opts["checkpoint"] == target
        elif shipped_preset:
            mine = reads == "masp" and trained_preset(rec["scenario"]) == shipped_preset
        elif packaged:
            method, preset, _, presets = packaged
            mine = reads == method and packaged_preset(rec["scenario"], list(presets)) == preset
        else:
            mine = False
        if mine and "seeds" in rec:
            out.append(str(Path(rec["path"]).resolve().relative_to(root.resolve())))
    return tuple(out)


def _read_history(path: Path) -> tuple[dict | None, str | None]:
    """``(kept history or None, why it is not used or None)``: a missing file is no history; a file that does
    not read as a history object is named with the reason (its run is planned all the same, untimed)."""
    if not path.exists():
        return None, None
    data = read_bounded(path, what="kept history")
    try:
        history = json.loads(data)
    except (ValueError, RecursionError) as e:  # not JSON: one error naming the file
        raise ValueError(f"{path}: expected a JSON kept history, could not parse it ({e})") from None
    if not isinstance(history, dict) or not isinstance(history.get("stages"), list):
        return None, "its stages are malformed (expected an object with a list of stages)"
    return history, None


def read_plan(root) -> tuple[list[Run], list[tuple[str, str]]]:
    """``(runs, left out)``: a :class:`Run` for every recipe, seed in :data:`SEEDS` and kept stage, and
    ``(name, reason)`` for each kept history under ``root/results/training`` that no recipe makes."""
    root = Path(root)
    base = root / "results" / "training"
    shipped = json.loads(read_bounded(root / "masp_lite/weights/manifest.json", what="manifest")) \
        if (root / "masp_lite/weights/manifest.json").exists() else {}
    shipped_by_history = {v["history"]: k for k, v in shipped.items() if not v.get("trained_on")}
    records = load_records(root / "results")
    packaged = _packaged(root)
    runs, skipped = [], []
    for recipe in RECIPES.values():
        for stage in (s for s in recipe.stages if s.keep):
            for seed in SEEDS:
                name = f"{stage.keep}-seed{seed}"
                path = base / f"{name}.manifest.json"
                preset = shipped_by_history.get(str(path.relative_to(root)))
                history, why = _read_history(path)
                if why:
                    skipped.append((name, why))
                stages = _run_stages(recipe, stage, seed, history)
                note = f"recipe {recipe.name}, stage {stage.name}, training seed {seed}"
                if history is not None and stages[-1].wall_clock_s is not None:  # kept: its own note
                    note = history.get("note") or note
                copy = packaged.get(f"results/training/{name}.pt")
                runs.append(Run(name, stages, preset is not None, note, _records(records, root, name, preset, copy),
                                copy and copy[2]))
    planned = {r.name for r in runs}
    kept = (str(p.relative_to(base))[: -len(".manifest.json")] for p in sorted(base.rglob("*.manifest.json")))
    skipped += [(name, "no recipe makes it (masp_lite.recipes)") for name in kept if name not in planned]
    return runs, skipped


def save_plan(runs, path) -> None:
    """Write a plan as JSON (a list of runs), the form ``reproduce --train --plan FILE`` reads."""
    atomic_write(path, (json.dumps([asdict(r) for r in runs], indent=1) + "\n").encode())


def load_plan(path) -> list[Run]:
    """A plan written by :func:`save_plan` (or by hand, in that form); one clear error otherwise."""
    try:
        data = json.loads(read_bounded(path, what="plan"))
        runs = [Run(**{**r, "stages": tuple(Stage(**s) for s in r["stages"]), "records": tuple(r["records"])})
                for r in data]
        for r in runs:
            for s in r.stages:
                TrainConfig.from_flat(s.config)
                get_scenario(s.scenario)
        _check_plan_paths(runs)
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RecursionError) as e:
        raise ValueError(f"--plan {path}: expected a JSON list of runs as save_plan writes them ({e})") from None
    return runs


def _check_plan_paths(runs) -> None:
    """A plan writes only inside its root: every run name and record path relative, with no ``..``; records
    under ``results/`` and ending ``.json``; every stage starting from random networks or an earlier stage."""
    def inside(text, what):
        parts = Path(str(text)).parts
        if not isinstance(text, str) or not text or Path(text).is_absolute() or ".." in parts or "\\" in text:
            raise ValueError(f"{what} {text!r}: expected a relative path inside the root, without '..'")
        return parts
    for r in runs:
        inside(r.name, "run name")
        if r.packaged is not None and (inside(r.packaged, "packaged weights")[:3] != ("masp_lite", "weights", "methods")
                                       or not r.packaged.endswith(".pt")):
            raise ValueError(f"packaged weights {r.packaged!r}: expected a masp_lite/weights/methods/....pt path")
        for rel in r.records:
            if inside(rel, "record")[0] != "results" or not rel.endswith(".json"):
                raise ValueError(f"record {rel!r}: expected a results/....json path")
        for k, s in enumerate(r.stages):
            if s.init is not None and (not isinstance(s.init, int) or isinstance(s.init, bool) or not 0 <= s.init < k):
                raise ValueError(f"run {r.name!r} stage {k + 1}: init {s.init!r}; expected an earlier stage's index")


def _key(run: Run, k: int) -> str:
    """The stage folder's name: the preset, seed and a hash of the stage and all it starts from."""
    chain, i = [], k
    while i is not None:
        s = run.stages[i]
        chain.append([s.scenario, s.seed, s.config, s.overrides])
        i = s.init
    digest = hashlib.sha256(json.dumps(chain, sort_keys=True).encode()).hexdigest()[:10]
    s = run.stages[k]
    return f"{s.scenario}-seed{s.seed}-{digest}"


def _tasks(runs) -> list[list[Run]]:
    """Runs grouped so that runs sharing a stage are in one task (they run in turn there)."""
    groups: list[tuple[set, list]] = []
    for run in runs:
        keys = {_key(run, k) for k in range(len(run.stages))}
        touching = [g for g in groups if g[0] & keys]
        merged = (keys.union(*(g[0] for g in touching)), [r for g in touching for r in g[1]] + [run])
        groups = [g for g in groups if g not in touching] + [merged]
    return [g[1] for g in groups]


def _wall(runs) -> float:
    """Wall-clock of training ``runs`` as kept, each shared stage counted once (unknown ones as 0)."""
    return sum({_key(r, k): s.wall_clock_s or 0.0 for r in runs for k, s in enumerate(r.stages)}.values())


def _lpt(durations, workers: int) -> float:
    """Makespan of the longest-first schedule of ``durations`` on ``workers``."""
    load = [0.0] * max(1, workers)
    for d in sorted(durations, reverse=True):
        load[load.index(min(load))] += d
    return max(load)


def describe(runs, skipped=(), workers: int = 1) -> str:
    """The plan as text: each run's stages, env steps and wall-clock (as kept), the totals."""
    lines = [f"{len(runs)} training runs ({sum(len(r.stages) for r in runs)} stages) from the recipes "
             "(masp_lite.recipes); wall-clock as measured when the kept runs were trained here (2 cores, one run per "
             "core; older runs predate today's kernels), 'not run yet' where no kept run matches its recipe:"]
    for r in runs:
        where = "masp_lite/weights/" if r.shipped else "results/training/"
        took = "  not run yet" if r.wall_clock_s is None else f"{r.wall_clock_s / 60:6.1f} min"
        lines.append(f"  {r.name:<28} {r.env_steps:>10,} env steps {took}  -> {where}, {len(r.records)} record(s)")
        for k, s in enumerate(r.stages, 1):
            start = "random networks" if s.init is None else f"stage {s.init + 1}"
            lines.append(f"      {k}. {s.method} on {s.scenario}, seed {s.seed}, {s.config['updates']} iterations "
                         f"x {s.config['num_envs']} worlds from {start}, {s.threads} thread(s)")
    tasks = _tasks(runs)
    unknown = sum(r.wall_clock_s is None for r in runs)
    lines.append(f"total: {_wall(runs) / 3600:.1f} h of training in turn (stages two runs share train once); "
                 f"{_lpt([_wall(t) for t in tasks], workers) / 3600:.1f} h as {len(tasks)} task(s) on {workers} "
                 "worker(s)" + (f", {unknown} run(s) not timed yet" if unknown else "")
                 + "; the evaluations come on top")
    for name, why in skipped:
        lines.append(f"  kept history not used: {name}: {why}")
    return "\n".join(lines)


def _train_stage(run: Run, k: int, root: Path, say) -> Path:
    s = run.stages[k]
    out = root / STAGES_DIR / _key(run, k)
    if (out / "manifest.json").exists():
        return out
    init = None if s.init is None else _train_stage(run, s.init, root, say) / "weights.pt"
    resume = (out / "state.pt").exists()
    say(f"{run.name}: stage {k + 1}/{len(run.stages)} ({s.scenario}) {'resumed' if resume else 'started'} in {out}")
    torch.set_num_threads(s.threads)
    train(s.scenario, TrainConfig.from_flat(s.config), out, seed=s.seed, resume=resume, init=init,
          overrides=s.overrides, progress=False, method=s.method,
          command=f"python -m masp_lite reproduce --train --only {run.name}  # stage {k + 1}")
    return out


def _remake(root: Path, rel: str, weights: Path) -> None:
    rec = json.loads(read_bounded(root / rel, what="record"))
    opts = dict(rec.get("method_options", {}))
    new = evaluate(rec["method"], rec["scenario"], episodes=rec["episodes_per_seed"], seeds=rec["seeds"],
                   overrides=rec.get("overrides"), num_envs=rec.get("num_envs"),
                   method_options={k: v for k, v in opts.items() if k != "checkpoint"}, checkpoint=weights)
    new.pop("method_options", None)
    if opts:  # as the record names them: a kept checkpoint relative to the root, none for default weights
        new["method_options"] = opts
    atomic_write(root / rel, (json.dumps(new, indent=2) + "\n").encode())


def _repackage(root: Path, packaged: str, weights: Path) -> None:
    """The package's copy of a method's seed-0 weights (``packaged``) replaced by the retrained ``weights``,
    and its hash in the methods' manifest."""
    manifest = json.loads(read_bounded(root / METHODS_MANIFEST, what="manifest"))
    file = Path(packaged).relative_to(Path(METHODS_MANIFEST).parent).as_posix()
    entry = next(e for presets in manifest.values() for e in presets.values() if e["file"] == file)
    blob = read_bounded(weights, what="weights file")
    atomic_write(root / packaged, blob)
    entry["sha256"] = hashlib.sha256(blob).hexdigest()
    atomic_write(root / METHODS_MANIFEST, (json.dumps(manifest, indent=2) + "\n").encode())


def _run_task(task, root: str, say=print) -> list[str]:
    """Train, ship and evaluate the runs of one task; returns their names. Skips finished runs."""
    root = Path(root)
    done = []
    for run in task:
        marker = root / STAGES_DIR / "done" / f"{run.name.replace('/', '__')}.json"
        if marker.exists():
            done.append(run.name)
            continue
        dirs = [_train_stage(run, k, root, say) for k in range(len(run.stages))]
        history_dir = root / "results" / "training" / Path(run.name).parent
        ship_run(dirs[-1], history_dir, root / "masp_lite" / "weights" if run.shipped else None,
                 earlier=[(d / "manifest.json", d / "progress.csv") for d in dirs[:-1]], note=run.note)
        preset = base_scenario(run.stages[-1].scenario)
        weights = root / ("masp_lite/weights" if run.shipped else "results/training") / \
            (f"{preset}.pt" if run.shipped else f"{run.name}.pt")
        if run.packaged:
            _repackage(root, run.packaged, weights)
        for rel in run.records:
            say(f"{run.name}: evaluating {rel}")
            _remake(root, rel, weights)
        marker.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(marker, json.dumps({"weights_sha256": sha256(weights)}).encode())
        done.append(run.name)
    return done


def run_plan(runs, root, use_ray: bool | None = None, address: str | None = None, say=print) -> list[str]:
    """Run the plan in ``root``; returns the names of the finished runs.

    ``use_ray``: None uses Ray when it is installed (else the runs go in turn, and ``say``
    tells how to install it), True requires it, False runs in turn. ``address``: a running
    Ray cluster (default: a local Ray on this machine's cores)."""
    _check_plan_paths(runs)
    root = Path(root).resolve()
    tasks = _tasks(runs)
    if use_ray is not False:
        try:
            import ray
        except ImportError:
            if use_ray:
                raise ValueError(f"Ray is not installed; install it with {RAY_INSTALL}") from None
            say(f"Ray is not installed: the {len(tasks)} task(s) run in turn. To run them side by side: {RAY_INSTALL}")
        else:
            return _run_on_ray(ray, tasks, root, address, say)
    return [name for task in tasks for name in _run_task(task, str(root), say)]


def _run_on_ray(ray, tasks, root: Path, address, say) -> list[str]:
    started = not ray.is_initialized()
    if started:
        kwargs = {"address": address} if address else {"num_cpus": os.cpu_count()}
        ray.init(include_dashboard=False, log_to_driver=False, **kwargs)
    try:
        say(f"Ray: {len(tasks)} task(s) on {ray.cluster_resources().get('CPU', 0):.0f} CPU(s)")
        remote = ray.remote(_run_task)
        refs = [remote.options(num_cpus=max(s.threads for r in t for s in r.stages)).remote(t, str(root), _quiet)
                for t in tasks]
        return [name for ref in refs for name in ray.get(ref)]
    finally:
        if started:
            with contextlib.suppress(Exception):
                ray.shutdown()


def _quiet(message: str) -> None:
    """What a Ray task says goes to its worker's log (the driver prints the task's result)."""
    print(message, flush=True)
