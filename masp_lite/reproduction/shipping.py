"""Keeping a finished training run in a source checkout: its weights shipped, its whole history kept.

:func:`ship_run` copies a finished run's weights into a weights folder (the source tree's
``masp_lite/weights/``, given explicitly: nothing is written into an installed package) and
its whole history (manifests and curves of every stage) into a history folder
(``results/training/``); :func:`ship_zero_shot` ships one preset's weights for another.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..files import atomic_write, read_bounded, sha256
from ..weights import read_weights, trained_world, weights_bytes

__all__ = ["ship_run", "ship_zero_shot"]

_RUN_INFO = ("command", "seed", "init", "iterations", "env_steps", "wall_clock_s", "started", "finished", "machine",
             "config", "final_eval")
_RUN_EXTRA = ("last_command", "overrides", "world", "method")  # absent from older manifests


def _json(path):
    """A JSON file read through the one bounded reader (a regular file, of bounded size)."""
    return json.loads(read_bounded(path, what="JSON file"))


def _curves(path) -> bytes | None:
    """A run's ``progress.csv`` (bounded read), or ``None`` when it has none."""
    return read_bounded(path, what="progress.csv") if Path(path).exists() else None


def _run_info(m: dict) -> dict:
    return {**{k: m[k] for k in _RUN_INFO}, **{k: m[k] for k in _RUN_EXTRA if k in m}}


def _read_run(manifest, progress):
    """``(scenario, run information, curves bytes or None)`` of one finished run."""
    sm = _json(manifest)
    missing = [key for key in _RUN_INFO if key not in sm]
    if missing:
        raise ValueError(f"{manifest}: expected a run manifest; missing {missing}")
    return sm.get("scenario"), _run_info(sm), _curves(progress)


def _earlier_runs(earlier):
    """The stages of ``earlier`` (see :func:`ship_run`), oldest first, as :func:`_read_run` gives them."""
    out = []
    for item in earlier:
        if isinstance(item, (str, Path)):  # a kept history: every stage, with its curves
            history = _json(item)
            if "stages" not in history:
                raise ValueError(f"{item}: expected a training history (SCENARIO-seedS.manifest.json)")
            for st in history["stages"]:
                curves = Path(item).parent / st["progress"]
                out.append((st["scenario"], st["training"], _curves(curves)))
        else:
            out.append(_read_run(*item))
    return out


def ship_zero_shot(weights_dir, scenario: str, source: str, note: str) -> dict:
    """Ship the weights of the preset ``source`` for the preset ``scenario`` as well, unchanged.

    The size-invariant networks then run zero-shot on ``scenario``: its entry in
    ``weights_dir/manifest.json`` copies ``source``'s (file, hash, history) and adds
    ``"trained_on": source`` and ``note`` (why no weights of its own ship). Returns the entry."""
    manifest_path = Path(weights_dir) / "manifest.json"
    manifest = _json(manifest_path) if manifest_path.exists() else {}
    if source not in manifest or manifest[source].get("trained_on"):
        raise ValueError(f"ship_zero_shot: expected shipped weights trained on {source!r}; the manifest has "
                         f"{sorted(k for k, v in manifest.items() if not v.get('trained_on'))}")
    manifest[scenario] = _zero_shot_entry(manifest, scenario, source, note)
    _write_json(manifest_path, manifest)
    return manifest[scenario]


def _zero_shot_entry(manifest: dict, scenario: str, source: str, note: str) -> dict:
    return {**manifest[source], "scenario": scenario, "trained_on": source, "note": note}


def _write_json(path, obj) -> None:
    atomic_write(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode())


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
    m = _json(run_dir / "manifest.json")
    rec = read_weights(run_dir / "weights.pt")
    name, seed = rec["scenario"], int(m["seed"])
    stem = f"{name}-seed{seed}"
    runs = [*_earlier_runs(earlier), _read_run(run_dir / "manifest.json", run_dir / "progress.csv")]
    stages = []
    for k, (scenario, info, curves) in enumerate(runs, start=1):
        target = f"{stem}.stage{k}.progress.csv" if k < len(runs) else f"{stem}.progress.csv"
        if curves is not None:
            atomic_write(history_dir / target, curves)
        stages.append({"scenario": scenario, "training": info, "progress": target})
    data = weights_bytes(run_dir / "weights.pt")  # as read_weights checked it
    if weights_dir is None:
        file, target = f"{stem}.pt", history_dir / f"{stem}.pt"
    else:
        file, target = f"{name}.pt", Path(weights_dir) / f"{name}.pt"
    atomic_write(target, data)
    digest = sha256(target)
    history = {"scenario": name, "world": trained_world(rec), "seed": seed, "file": file, "sha256": digest,
               "arch": rec["arch"],
               "evaluation": evaluation, "note": note, "stages": stages}
    _write_json(history_dir / f"{stem}.manifest.json", history)
    if weights_dir is not None:
        manifest_path = Path(weights_dir) / "manifest.json"
        manifest = _json(manifest_path) if manifest_path.exists() else {}
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
