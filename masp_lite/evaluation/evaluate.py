"""``evaluate``: a method on a scenario over several seeds — the record every table is made of.

The record is the ``evaluate --json`` format (``method``, ``scenario``, ``world`` — the
world definition it ran in, :attr:`~masp_lite.envs.Scenario.world` — ``seeds``, ``num_envs``
(the worlds side by side, over which ``decision_ms`` is amortised),
``episodes_per_seed``, ``sr``/``steps``/``cr``/``decision_ms`` as ``{"mean", "std"}``,
plus ``overrides`` and ``method_options`` when given, and the SHA-256 of the weights
file when a checkpoint is): the paper's "mean (standard
deviation) averaged over 300 testing episodes", pooled over seeds and episodes.
"""
from __future__ import annotations

import math
import os

import numpy as np
import torch

from ..envs import get_scenario, make
from ..files import sha256
from ..policies import build_policy, get_factory
from ..policies import method_options as method_options_of
from .metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate
from .rollouts import rollout_timings

__all__ = ["evaluate", "check_checkpoint", "MAX_ENVS", "memory_estimate", "check_memory"]

#: Most episodes run side by side in one batched world during evaluation.
MAX_ENVS = 100
#: Bytes per agent pair and world at the peak of an evaluation (pair features, groups, distances, the
#: networks' chunked activations), measured for ``masp`` at mpe-50's density: 134-149 at N = 200 to 1000
#: and 1 to 25 worlds (the planners need less); tested within 25 % at N = 500 and 1000.
PAIR_BYTES = 144
#: The interpreter, torch and one method's networks, before any world (measured: 279 MiB).
BASE_BYTES = 280 * 2 ** 20


def memory_estimate(num_agents: int, num_envs: int) -> int:
    """Bytes an evaluation of ``num_envs`` worlds of ``num_agents`` agents needs, roughly (it grows with N^2)."""
    return BASE_BYTES + PAIR_BYTES * num_envs * num_agents ** 2


def _available_bytes() -> int | None:
    """Memory this machine can still give (``MemAvailable``), or ``None`` where that is unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def check_memory(num_agents: int, num_envs: int, flag: str = "--num-envs ") -> None:
    """One ValueError, with the estimate and how many worlds fit, when ``num_envs`` worlds of ``num_agents``
    agents would need more memory than is available (:func:`memory_estimate`); ``flag`` spells the fix."""
    need, have = memory_estimate(num_agents, num_envs), _available_bytes()
    if have is not None and need > have:
        fit = max(0, (have - BASE_BYTES) // (PAIR_BYTES * num_agents ** 2))
        hint = f"pass num_envs={fit} ({flag}{fit}) or fewer" if fit >= 1 else "choose fewer agents"
        raise ValueError(f"{num_agents} agents in {num_envs} worlds side by side need about {need / 2 ** 30:.1f} GiB "
                         f"(memory grows with N^2: ~{PAIR_BYTES} bytes per agent pair and world), more than the "
                         f"{have / 2 ** 30:.1f} GiB available; {hint}")


def _stats(x: np.ndarray) -> dict:
    return {"mean": float(np.mean(x)), "std": float(np.std(x))}


def evaluate(method: str, scenario, episodes: int = 100, seeds=(0, 1, 2), overrides=None,
             method_options=None, checkpoint: str | os.PathLike | None = None, device: str = "cpu",
             num_envs: int | None = None, progress: bool = False, return_log: bool = False):
    """Evaluate ``method`` on ``scenario`` (a preset name or a :class:`~masp_lite.envs.Scenario`):
    ``episodes`` per seed, for every seed.

    Evaluation seed ``s`` seeds the world (spawns, team changes) via :func:`rollout`. If
    the method's factory has a parameter named ``seed`` it also receives ``seed=s`` (unless
    ``method_options`` sets it), so a random policy draws differently per seed and a
    learned method can load the checkpoint trained with seed ``s``. ``checkpoint``: the
    weights file of a learned method (a path; :func:`check_checkpoint` is its one check), given
    to the policy as its option ``checkpoint`` and kept in the record's ``method_options``, with
    its SHA-256. ``num_envs`` caps the batch (default
    ``min(episodes, MAX_ENVS)``); spawns are drawn per batch, so the same seed in another
    batch size gives other episodes (a record keeps ``num_envs`` so that it can be re-made).

    Returns the ``evaluate --json`` record: ``method``, ``scenario``, ``seeds``,
    ``episodes_per_seed`` and ``sr``/``steps``/``cr``/``decision_ms`` as ``{"mean", "std"}``.
    Means and standard deviations (population std, ``ddof=0``) are over *all episodes* of
    all seeds pooled (300 for the default), as the paper's "mean (standard deviation)
    averaged over 300 testing episodes"; ``decision_ms`` is over all ``act`` calls, in
    milliseconds per step of one world — amortised over the batch; ``num_envs=1`` measures
    the latency of deciding for a single team, the paper's per-step time. ``steps`` is
    ``{"mean": None, "std": None}`` when no episode reaches SR 1 (the paper's backslash).
    ``threads`` is torch's intra-op thread count during the run: a float sum may round
    differently with another count, and the drone world's flight amplifies such a difference
    into another trajectory, so a record re-evaluates exactly at the thread count it names.
    ``return_log=True`` returns ``(record, log)``: the :class:`EpisodeLog` of every episode too,
    for a per-episode look (e.g. Steps over the solved episodes only, chapter 11).
    """
    overrides = dict(overrides or {})
    sc = get_scenario(scenario, **overrides)  # the one lookup: the name and the overrides are checked here
    factory = get_factory(method, sc.kind)
    options = _options(factory, method, method_options, checkpoint)
    seeds = _check_seeds(seeds)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected a positive int, got {episodes!r}")
    if num_envs is not None and (isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1):
        raise ValueError(f"num_envs: expected a positive int (worlds per batch), got {num_envs!r}")
    B = min(episodes, num_envs or MAX_ENVS)
    check_memory(sc.num_agents, B)
    log, timings = _run_seeds(method, sc, factory, options, seeds, episodes, B, device, progress)
    steps_ = steps(log).numpy()
    record = {
        "method": method, "scenario": sc.name, "world": sc.world, "seeds": seeds, "episodes_per_seed": episodes,
        "num_envs": B, "threads": torch.get_num_threads(),
        "sr": _stats(success_rate(log).numpy()),
        "steps": _stats(steps_) if bool(reached_target(log).any()) else {"mean": None, "std": None},
        "cr": _stats(collision_rate(log).numpy()),
        "decision_ms": _stats(np.concatenate(timings) * 1e3),
        **({"overrides": overrides} if overrides else {}),
        **({"method_options": options} if options else {}),
        **({"checkpoint_sha256": sha256(checkpoint)} if checkpoint is not None else {}),
    }
    return (record, log) if return_log else record


def check_checkpoint(checkpoint, method: str, named: set, var_kw: bool, options: dict) -> None:
    """The one check of ``evaluate``'s checkpoint: a path (``str`` or ``os.PathLike``), for a method that
    takes weights, given once (``method_options`` never carries one: the record keeps it there)."""
    if "checkpoint" in options:
        raise ValueError("method option checkpoint: expected the weights file as evaluate's checkpoint=PATH "
                         "(--checkpoint PATH on the command line)")
    if checkpoint is None:
        return
    if isinstance(checkpoint, bool) or not isinstance(checkpoint, (str, os.PathLike)) or not os.fspath(checkpoint):
        raise ValueError(f"checkpoint: expected the path of a weights file, got {checkpoint!r}")
    if "checkpoint" not in named and not var_kw:
        raise ValueError(f"method {method!r} takes no checkpoint; expected a learned method")


def _options(factory, method: str, method_options, checkpoint) -> dict:
    """The options the policy is built with: ``method_options`` (names checked against the factory's) and the
    checkpoint (:func:`check_checkpoint`)."""
    options = dict(method_options or {})
    named, var_kw = method_options_of(factory)
    check_checkpoint(checkpoint, method, named, var_kw, options)
    bad = sorted(k for k in options if k not in named and not var_kw)
    if bad:
        raise ValueError(f"method {method!r}: unknown option(s) {bad}; expected one of {sorted(named)}")
    return {**options, **({"checkpoint": os.fspath(checkpoint)} if checkpoint is not None else {})}


def _check_seeds(seeds) -> list[int]:
    """``seeds`` as a list of distinct ints in ``[0, 2**63)``; one clear error otherwise."""
    seeds = list(seeds) if isinstance(seeds, (list, tuple, range)) else seeds
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, (int, np.integer)) and
                                                          not isinstance(s, bool) for s in seeds):
        raise ValueError(f"seeds: expected a non-empty list of ints, got {seeds!r}")
    seeds = [int(s) for s in seeds]
    bad = [s for s in seeds if not 0 <= s < 2 ** 63]
    if bad:
        raise ValueError(f"seeds: expected ints from 0 to 2**63 - 1, got {bad}")
    if len(set(seeds)) != len(seeds):  # the same episodes pooled twice would understate the std
        raise ValueError(f"seeds: expected distinct seeds, got {seeds} (a repeated seed repeats its episodes)")
    return seeds


def _run_seeds(method: str, sc, factory, options: dict, seeds: list[int], episodes: int, B: int, device,
               progress: bool):
    """``(EpisodeLog of every seed's episodes, each seed's decision times)``: a world of ``B`` episodes and a
    policy per seed (the policy gets ``seed=s`` when its factory names one)."""
    named, _ = method_options_of(factory)
    bar = None
    logs, timings = [], []
    try:
        for s in seeds:
            world = make(sc, num_envs=B, device=device, seed=s)
            policy = build_policy(factory, method, world, {"seed": s, **options} if "seed" in named else options)
            if progress and bar is None:  # once the first policy is built: bad options fail first
                from tqdm import tqdm
                bar = tqdm(total=len(seeds) * math.ceil(episodes / B) * world.horizon, unit="step",
                           desc=f"{method} on {sc.name}", leave=False)
            log, dt = rollout_timings(world, policy, episodes, s, progress=bar)
            logs.append(log)
            timings.append(dt)
    finally:
        if bar is not None:
            bar.refresh()  # tqdm draws at most every 0.1 s: its last frame would stop short of the total
            bar.close()
    return EpisodeLog.cat(logs), timings
