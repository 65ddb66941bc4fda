"""Metrics (SR, Steps, CR), batched rollouts, multi-seed evaluation and paper-format tables.

The paper's metrics (section "Metrics") are defined once, here, on an :class:`EpisodeLog`:

* :func:`success_rate` — **SR**, "the average ratio of landmarks reached by the agents to
  the total landmarks per episode". A landmark is reached when an alive agent is within
  ``r_agent + r_landmark``. Fixed teams: the fraction of landmarks covered *at the end* of
  the episode (the task is to cover all at once). Varying teams: the fraction *ever*
  reached ("the ratio of the landmarks reached during the navigation", section
  "Varying Team Sizes").
* :func:`steps` — **Steps**, "the average timesteps required to achieve a target Success
  Rate" (the target is SR = 1): per episode, the first ``t`` at which the SR-so-far is 1
  (fixed: every landmark covered at that same step; varying: every landmark reached by
  then). ``t`` counts environment steps taken, so ``t = 0`` (solved at spawn) is allowed
  and means zero steps were required. An episode that never gets there counts as the
  horizon. When *no* episode gets there the paper prints a backslash; :func:`evaluate`
  reports ``null`` and :func:`format_table` prints ``\\``.
* :func:`collision_rate` — **CR**, "the average ratio of collision occurrences to the total
  number of environmental steps per episode": collision events (agent–agent and
  agent–obstacle pairs in contact after a step, alive agents only) summed over the episode
  and divided by its number of steps ``T``.

For fixed teams SR and Steps can disagree: an episode may cover every landmark at step 12
(Steps 12) and lose one to a collision before the end (SR 0.8). Both are reported as the
paper defines them.

:func:`rollout` runs episodes on a batched world timing only ``policy.act`` (decision
time); :func:`evaluate` repeats it over seeds and returns the JSON record of the
``evaluate`` command; :func:`format_table` prints records as the paper's tables. The
``evaluate`` command (``add_arguments``/``run``) is at the bottom of this module; nothing
here is hand-written that a library offers (tqdm draws the progress bar, argparse parses).
"""
from __future__ import annotations

import importlib
import inspect
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .tables import format_table  # noqa: F401  (re-exported: tables of evaluate() records)

__all__ = ["EpisodeLog", "success_rate", "steps", "collision_rate", "reached_target", "rollout", "contact_breakdown",
           "evaluate", "build_policy", "format_table", "parse_sets", "parse_value", "MAX_ENVS",
           "add_arguments", "run"]

#: Most episodes run side by side in one batched world during evaluation.
MAX_ENVS = 100


@dataclass
class EpisodeLog:
    """What the metrics need from a batch of ``E`` episodes of ``T`` steps (``T`` = horizon).

    Index ``t`` of the ``T + 1`` axis is the state after ``t`` steps (``t = 0``: at reset).
    """

    covered: torch.Tensor
    """(E, T + 1, L) bool — landmark covered by an alive agent at step t."""
    reached: torch.Tensor
    """(E, T + 1, L) bool — landmark reached at some step <= t."""
    collisions: torch.Tensor
    """(E, T) long — collision events after step t + 1 (contact pairs)."""
    alive: torch.Tensor
    """(E, T + 1, N) bool — agents in the team at step t."""
    varying: bool
    """True when the team size changes (SR and Steps then use ``reached``)."""
    horizon: int
    """Steps per episode; the Steps value of an episode that never reaches SR 1."""

    def __post_init__(self):
        cov, rea, col, alive = self.covered, self.reached, self.collisions, self.alive
        shapes = [tuple(x.shape) if torch.is_tensor(x) else type(x).__name__ for x in (cov, rea, col, alive)]
        ok = all(torch.is_tensor(x) for x in (cov, rea, col, alive)) and cov.dim() == 3 and \
            rea.shape == cov.shape and col.shape == cov.shape[:1] + (cov.shape[1] - 1,) and \
            alive.dim() == 3 and alive.shape[:2] == cov.shape[:2] and \
            cov.dtype == rea.dtype == alive.dtype == torch.bool and not col.dtype.is_floating_point
        if not ok:
            raise ValueError("EpisodeLog: expected bool covered/reached (E, T+1, L), integer collisions "
                             f"(E, T) and bool alive (E, T+1, N); got shapes {shapes}")
        if isinstance(self.horizon, bool) or not isinstance(self.horizon, int) or self.horizon < 1:
            raise ValueError(f"EpisodeLog.horizon: expected a positive int, got {self.horizon!r}")

    @classmethod
    def cat(cls, logs: list[EpisodeLog]) -> EpisodeLog:
        """Episodes of several logs (same horizon and team rule) in one log."""
        if not logs:
            raise ValueError("EpisodeLog.cat: expected at least one log")
        first = logs[0]
        if any(lg.varying != first.varying or lg.horizon != first.horizon for lg in logs):
            raise ValueError("EpisodeLog.cat: expected logs with the same horizon and varying flag")
        fields = ("covered", "reached", "collisions", "alive")
        return cls(*(torch.cat([getattr(lg, f) for lg in logs]) for f in fields),
                   varying=first.varying, horizon=first.horizon)


def _solved(log: EpisodeLog) -> torch.Tensor:
    """(E, T + 1) bool: the SR-so-far is 1 at step t (fixed: all covered; varying: all reached)."""
    return (log.reached if log.varying else log.covered).all(dim=-1)


def success_rate(log: EpisodeLog) -> torch.Tensor:
    """SR per episode, float64 (E,): final coverage (fixed teams) or ever reached (varying)."""
    final = log.reached[:, -1] if log.varying else log.covered[:, -1]
    return final.double().mean(dim=-1)


def steps(log: EpisodeLog) -> torch.Tensor:
    """Steps per episode, float64 (E,): first t in [0, T] with SR-so-far 1, else the horizon."""
    solved = _solved(log)
    T1 = solved.shape[1]
    t = torch.arange(T1, device=solved.device).expand_as(solved)
    first = torch.where(solved, t, torch.full_like(t, T1)).min(dim=1).values
    return torch.where(first < T1, first, torch.full_like(first, log.horizon)).double()


def reached_target(log: EpisodeLog) -> torch.Tensor:
    """(E,) bool: the episode reached SR 1 at some step (used for the Steps backslash)."""
    return _solved(log).any(dim=1)


def collision_rate(log: EpisodeLog) -> torch.Tensor:
    """CR per episode, float64 (E,): collision events summed over the episode / its T steps."""
    return log.collisions.sum(dim=1).double() / log.collisions.shape[1]


# ----------------------------------------------------------------------------- rollouts
def _sync(device) -> None:
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)


def _rollout(world, policy, episodes: int, seed: int | None, progress=None, on_step=None):
    """Episodes in batches of ``world.num_envs``; returns (log, per-act seconds per world).

    ``on_step(obs, keep)``, when given, sees the observation after every step and how many
    leading worlds of the batch are episodes that count.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected a positive int, got {episodes!r}")
    B, T = world.num_envs, world.horizon
    device = getattr(world, "device", "cpu")
    logs, timings = [], []
    done_eps = 0
    first = True
    while done_eps < episodes:
        obs = world.reset(seed=seed if first else None)  # later batches continue the world's RNG
        first = False
        policy.reset(obs)
        cov, rea, alive, col = [obs["covered"]], [obs["reached"]], [obs["alive"]], []
        keep = min(B, episodes - done_eps)
        for _ in range(T):
            _sync(device)
            t0 = time.perf_counter()
            actions = policy.act(obs)
            _sync(device)
            timings.append((time.perf_counter() - t0) / B)
            obs, info = world.step(actions)
            cov.append(info["covered"])
            rea.append(info["reached"])
            alive.append(info["alive"])
            col.append(info["collisions"])
            if on_step is not None:
                on_step(obs, keep)
            if progress is not None:
                progress.update(1)
        stack = lambda xs: torch.stack(xs, dim=1)[:keep].cpu()  # noqa: E731
        logs.append(EpisodeLog(stack(cov), stack(rea), stack(col).long(), stack(alive),
                               varying=bool(world.scenario.varying), horizon=int(T)))
        done_eps += keep
    return EpisodeLog.cat(logs), np.asarray(timings)


def rollout(world, policy, episodes: int, seed: int | None = None):
    """Run ``episodes`` episodes of ``policy`` on the batched ``world``.

    Episodes run ``world.num_envs`` at a time (the last batch is trimmed); the first batch
    starts with ``world.reset(seed=seed)`` and later ones continue the world's generator,
    so the same seed and batch size give the same episodes. Works for any world honouring
    the observation/info contract (particle and drone worlds; actions are passed through
    untouched).

    Returns ``(log, decision_seconds_per_step)``: the :class:`EpisodeLog` and the mean
    wall time of ``policy.act`` per step *of one world* — each call is timed with
    ``time.perf_counter`` (CUDA synchronised around it) and divided by ``num_envs``, the
    worlds it decides for. The environment's own step is not timed.
    """
    log, timings = _rollout(world, policy, episodes, seed)
    return log, float(timings.mean())


CONTACT_KINDS = ("agent-agent, both on landmarks", "agent-agent, en route", "agent-obstacle, on a landmark",
                 "agent-obstacle, en route")
"""The four parts of CR that :func:`contact_breakdown` reports."""


def contact_breakdown(world, policy, episodes: int, seed: int | None = None) -> dict[str, float]:
    """Where a policy's contacts happen on a particle world: CR split four ways.

    Runs ``episodes`` episodes as :func:`rollout` does (same seed, same episodes) and
    counts every contact after every step, as CR does. An agent is *on a landmark* when
    it is within reach of any landmark after the step. An agent–agent contact is "both on
    landmarks" when both agents are, else "en route"; an agent–obstacle contact is "on a
    landmark" when the agent is. Returns the mean contacts per step of each kind
    (:data:`CONTACT_KINDS`) and their sum under ``"total"``, which equals the mean CR.
    """
    sc = world.scenario
    if sc.kind != "particle":
        raise ValueError(f"contact_breakdown: expected a particle world, got scenario {sc.name!r}")
    sums = torch.zeros(len(CONTACT_KINDS), dtype=torch.float64)
    exact = "donot_use_mm_for_euclid_dist"  # the world's own distances, no matmul shortcut

    def count(obs, keep):
        pos, alive = obs["agent_pos"][:keep], obs["alive"][:keep]
        on = (torch.cdist(pos, obs["landmark_pos"][:keep]) <= sc.reach_distance).any(-1) & alive
        aa = torch.triu(torch.cdist(pos, pos, compute_mode=exact) < 2 * sc.agent_radius, diagonal=1)
        aa &= alive.unsqueeze(2) & alive.unsqueeze(1)
        both = on.unsqueeze(2) & on.unsqueeze(1)
        ao = torch.cdist(pos, obs["obstacle_pos"][:keep], compute_mode=exact) < sc.agent_radius + sc.obstacle_radius
        ao &= alive.unsqueeze(2)
        sums.add_(torch.stack([(aa & both).sum(), (aa & ~both).sum(), (ao & on.unsqueeze(2)).sum(),
                               (ao & ~on.unsqueeze(2)).sum()]).double())

    _rollout(world, policy, episodes, seed, on_step=count)  # the same batches and seeds as rollout()
    T = world.horizon
    parts = {k: float(v) / (episodes * T) for k, v in zip(CONTACT_KINDS, sums)}
    return {**parts, "total": float(sums.sum()) / (episodes * T)}


# --------------------------------------------------------------------------- evaluation
def _factory(method: str):
    from .methods import METHODS, method_names
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {method_names()}")
    module_name, attr = METHODS[method].split(":")
    return getattr(importlib.import_module(module_name), attr)


def _method_params(factory) -> tuple[set[str], bool]:
    """Named options a factory accepts (besides the world) and whether it takes ``**options``."""
    target = factory.__init__ if inspect.isclass(factory) else factory
    params = list(inspect.signature(target).parameters.values())
    if inspect.isclass(factory):
        params = params[1:]  # self
    params = params[1:]  # the world
    named = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return named, any(p.kind == p.VAR_KEYWORD for p in params)


def build_policy(factory, method: str, world, options: dict):
    """``factory(world, **options)``, with a wrong option reported as one ValueError.

    A method that takes ``**options`` checks their names itself; when it rejects one, the
    message also lists the scenario overrides, so a misspelt ``--set`` key shows both lists.
    """
    from .envs import OVERRIDES
    try:
        return factory(world, **options)
    except TypeError as e:
        raise ValueError(f"method {method!r}: bad option(s) {sorted(options)} ({e}); scenario "
                         f"overrides are {sorted(OVERRIDES)}") from None
    except ValueError as e:
        if any(k in str(e) for k in options):
            raise ValueError(f"{e}; scenario overrides are {sorted(OVERRIDES)}") from None
        raise


def _stats(x: np.ndarray) -> dict:
    return {"mean": float(np.mean(x)), "std": float(np.std(x))}


def evaluate(method: str, scenario: str, episodes: int = 100, seeds=(0, 1, 2), overrides=None,
             method_options=None, checkpoint=None, device: str = "cpu", num_envs: int | None = None,
             progress: bool = False) -> dict:
    """Evaluate ``method`` on ``scenario``: ``episodes`` per seed, for every seed.

    Evaluation seed ``s`` seeds the world (spawns, team changes) via :func:`rollout`. If
    the method's factory has a parameter named ``seed`` it also receives ``seed=s`` (unless
    ``method_options`` sets it), so a random policy draws differently per seed and a
    learned method can load the checkpoint trained with seed ``s``. ``checkpoint`` is
    passed as the option ``checkpoint``. ``num_envs`` caps the batch (default
    ``min(episodes, MAX_ENVS)``).

    Returns the ``evaluate --json`` record: ``method``, ``scenario``, ``seeds``,
    ``episodes_per_seed`` and ``sr``/``steps``/``cr``/``decision_ms`` as ``{"mean", "std"}``.
    Means and standard deviations (population std, ``ddof=0``) are over *all episodes* of
    all seeds pooled (300 for the default), as the paper's "mean (standard deviation)
    averaged over 300 testing episodes"; ``decision_ms`` is over all ``act`` calls, in
    milliseconds per step of one world — amortised over the batch; ``num_envs=1`` measures
    the latency of deciding for a single team, the paper's per-step time. ``steps`` is ``{"mean": None, "std": None}`` when
    no episode reaches SR 1 (the paper's backslash).
    """
    from .envs import OVERRIDES, make
    overrides = dict(overrides or {})
    options = dict(method_options or {})
    factory = _factory(method)
    named, var_kw = _method_params(factory)
    bad = sorted(k for k in overrides if k not in OVERRIDES)
    if bad:
        raise ValueError(f"unknown scenario override(s) {bad}; expected one of {sorted(OVERRIDES)}")
    bad = sorted(k for k in options if k not in named and not var_kw)
    if bad:
        raise ValueError(f"method {method!r}: unknown option(s) {bad}; expected one of {sorted(named)}")
    if checkpoint is not None:
        if "checkpoint" not in named and not var_kw:
            raise ValueError(f"method {method!r} takes no checkpoint; expected a learned method")
        options["checkpoint"] = str(checkpoint)
    seeds = list(seeds) if isinstance(seeds, (list, tuple, range)) else seeds
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, (int, np.integer)) and
                                                          not isinstance(s, bool) for s in seeds):
        raise ValueError(f"seeds: expected a non-empty list of ints, got {seeds!r}")
    seeds = [int(s) for s in seeds]
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected a positive int, got {episodes!r}")
    B = min(episodes, num_envs or MAX_ENVS)
    bar = None
    logs, timings = [], []
    try:
        for s in seeds:
            world = make(scenario, num_envs=B, device=device, seed=s, **overrides)
            opts = dict(options)
            if "seed" in named:
                opts.setdefault("seed", s)
            policy = build_policy(factory, method, world, opts)
            if progress and bar is None:  # once the first policy is built: bad options fail first
                from tqdm import tqdm
                bar = tqdm(total=len(seeds) * math.ceil(episodes / B) * world.horizon, unit="step",
                           desc=f"{method} on {getattr(world.scenario, 'name', scenario)}", leave=False)
            log, dt = _rollout(world, policy, episodes, s, progress=bar)
            logs.append(log)
            timings.append(dt)
    finally:
        if bar is not None:
            bar.close()
    log = EpisodeLog.cat(logs)
    sc_name = scenario if isinstance(scenario, str) else scenario.name
    steps_ = steps(log).numpy()
    any_solved = bool(reached_target(log).any())
    return {
        "method": method, "scenario": sc_name, "seeds": seeds, "episodes_per_seed": episodes,
        "sr": _stats(success_rate(log).numpy()),
        "steps": _stats(steps_) if any_solved else {"mean": None, "std": None},
        "cr": _stats(collision_rate(log).numpy()),
        "decision_ms": _stats(np.concatenate(timings) * 1e3),
        **({"overrides": overrides} if overrides else {}),
        **({"method_options": options} if options else {}),
    }


# ---------------------------------------------------------------------------------- CLI
def parse_value(text: str):
    """``--set`` value: int, then float, then true/false, then none/null, else the string."""
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    return text


def parse_sets(items, method: str) -> tuple[dict, dict]:
    """Split ``KEY=VALUE`` strings into (scenario overrides, method options).

    Keys in :data:`masp_lite.envs.OVERRIDES` go to the scenario; other keys go to the
    method if its factory accepts them; anything else is an error naming both lists.
    """
    from .envs import OVERRIDES
    named, var_kw = _method_params(_factory(method))
    overrides, options = {}, {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE")
        if key in OVERRIDES:
            overrides[key] = parse_value(value)
        elif key in named or var_kw:
            options[key] = parse_value(value)
        else:
            raise ValueError(f"--set {key}: not a scenario override {sorted(OVERRIDES)} nor an "
                             f"option of method {method!r} {sorted(named)}")
    return overrides, options


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, help="method name (see masp_lite.methods)")
    parser.add_argument("--scenario", required=True, help="scenario preset, e.g. mpe-20")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per seed (default 100)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="evaluation seeds")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override or method option (repeatable)")
    parser.add_argument("--checkpoint", default=None, help="weights for a learned method")
    parser.add_argument("--json", default=None, help="write the result record to this file")
    parser.add_argument("--device", default="cpu", help="torch device (default cpu)")
    parser.add_argument("--num-envs", type=int, default=None, help=f"batch size (default ≤ {MAX_ENVS})")
    parser.add_argument("--format", default="markdown", choices=["markdown", "text", "latex"],
                        help="table format printed on stdout")


def run(args) -> int:
    overrides, options = parse_sets(args.set, args.method)
    record = evaluate(args.method, args.scenario, episodes=args.episodes, seeds=args.seeds,
                      overrides=overrides, method_options=options, checkpoint=args.checkpoint,
                      device=args.device, num_envs=args.num_envs, progress=True)
    print(format_table([record], fmt=args.format))
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record, indent=2) + "\n")
    return 0
