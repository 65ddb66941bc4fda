"""Record one episode of a method and write it to a file (the ``play`` command's work).

* ``.gif`` / ``.mp4`` on a particle scenario: a 2-D animation (:mod:`.anim2d`) titled with
  the method, with a colour key, short trails and — with ``goals=True`` — a line from each
  agent to the goal the policy currently pursues;
* ``.html``, and every drone scenario: a standalone 3-D meshcat page from
  :func:`masp_lite.viz.meshcat3d.record_episode` and :func:`~masp_lite.viz.meshcat3d.episode_html`.

:func:`play` also returns the episode's SR, Steps and CR, computed by the evaluation's own
metrics (:mod:`masp_lite.evaluation.metrics`); a 2-D animation ends at the step the episode is
solved (SR 1), so a 51-step episode is not followed by 40 still frames.
"""
from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import torch

from ..envs import get_scenario, make
from ..evaluation.metrics import EpisodeLog, collision_rate, reached_target, steps, success_rate
from ..files import atomic_write
from ..policies import build_policy, get_factory
from ..policies import method_options as options_of

__all__ = ["play", "frames_log", "summary"]


def frames_log(frames: list[dict]) -> EpisodeLog:
    """The :class:`EpisodeLog` of one recorded 2-D episode (``anim2d.record``'s frames)."""
    stack = lambda key: torch.from_numpy(np.stack([f[key] for f in frames]))[None]  # noqa: E731
    total = torch.tensor([f["collisions"] for f in frames])
    return EpisodeLog(stack("covered"), stack("reached"), (total[1:] - total[:-1])[None], stack("alive"),
                      varying=frames[0]["varying"], horizon=frames[0]["horizon"])


def summary(log: EpisodeLog) -> dict:
    """``{"sr", "steps", "cr"}`` of a one-episode log; ``steps`` is ``None`` when it never reached SR 1."""
    return {"sr": float(success_rate(log)[0]), "cr": float(collision_rate(log)[0]),
            "steps": float(steps(log)[0]) if bool(reached_target(log)[0]) else None}


def play(method: str, scenario: str, out, seed: int = 0, overrides=None, method_options=None,
         goals: bool = False) -> tuple[Path, dict]:
    """Record one episode (world 0, seeded by ``seed``) and write it to ``out``; returns ``(path, summary)``.

    ``summary`` is the episode's ``{"sr", "steps", "cr"}`` (:func:`summary`). ``goals`` (2-D
    only) draws each agent's line to its current goal, when the method exposes goals.
    """
    overrides, options = dict(overrides or {}), dict(method_options or {})
    sc = get_scenario(scenario, **overrides)
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".gif", ".mp4", ".html"):
        raise ValueError(f"--out {out.name}: expected a .gif, .mp4 or .html file name")
    if suffix == ".html" or sc.kind == "drone":
        if suffix != ".html":
            raise ValueError(f"scenario {sc.name!r} is a drone scenario: expected an .html output (3-D)")
        if options:
            raise ValueError(f"the 3-D export takes scenario overrides only; got method option(s) "
                             f"{sorted(options)}")
        if goals:
            raise ValueError("goal lines are drawn in 2-D only; expected a .gif or .mp4 output for --goals")
        try:
            meshcat3d = importlib.import_module("masp_lite.viz.meshcat3d")
        except ModuleNotFoundError as e:
            raise ValueError(f"3-D playback is unavailable ({e}); expected masp_lite.viz.meshcat3d "
                             "and meshcat to be installed, or a .gif/.mp4 output") from None
        out.parent.mkdir(parents=True, exist_ok=True)
        episode = meshcat3d.record_episode(method, scenario, seed=seed, **overrides)
        atomic_write(out, meshcat3d.episode_html(episode))
        return out, summary(episode["log"])
    from .anim2d import animate, record, save

    factory = get_factory(method)
    world = make(scenario, num_envs=1, seed=seed, **overrides)
    if "seed" in options_of(factory)[0]:  # as evaluate does: the seed reaches the method too
        options.setdefault("seed", seed)
    policy = build_policy(factory, method, world, options)
    frames = record(world, policy, seed=seed)
    result = summary(frames_log(frames))
    if result["steps"] is not None:  # end at the step it was solved
        frames = frames[: int(result["steps"]) + 1]
    return save(animate(frames, title=f"{method} on {sc.name}", goals=goals), out), result
