"""Record one episode of a method and write it to a file (the ``play`` command's work).

* ``.gif`` / ``.mp4`` on a particle scenario: a 2-D animation (:mod:`.anim2d`) titled with
  the method, with a colour key, short trails and — with ``goals=True`` — a line from each
  agent to the goal the policy currently pursues;
* ``.html``, and every drone scenario: a standalone 3-D meshcat page from
  :func:`masp_lite.viz.meshcat3d.play_to_html`.
"""
from __future__ import annotations

import importlib
from pathlib import Path

from ..envs import get_scenario, make
from ..policies import build_policy, get_factory
from ..policies import method_options as options_of

__all__ = ["play"]


def play(method: str, scenario: str, out, seed: int = 0, overrides=None, method_options=None,
         goals: bool = False) -> Path:
    """Record one episode (world 0, seeded by ``seed``) and write it to ``out``; returns the path.

    ``goals`` (2-D only) draws each agent's line to its current goal, when the method exposes goals.
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
        meshcat3d.play_to_html(method, scenario, str(out), seed=seed, **overrides)
        return out
    from .anim2d import animate, record, save

    factory = get_factory(method)
    world = make(scenario, num_envs=1, seed=seed, **overrides)
    if "seed" in options_of(factory)[0]:  # as evaluate does: the seed reaches the method too
        options.setdefault("seed", seed)
    policy = build_policy(factory, method, world, options)
    return save(animate(record(world, policy, seed=seed), title=f"{method} on {sc.name}", goals=goals), out)
