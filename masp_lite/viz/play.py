"""The ``play`` command: record one episode of a method and write it to a file.

``python -m masp_lite play --method M --scenario S --out FILE [--seed 0] [--set KEY=VALUE ...]``

* ``.gif`` / ``.mp4`` on a particle scenario: a 2-D animation (:mod:`.anim2d`);
* ``.html``, and every drone scenario: a standalone 3-D meshcat page from
  ``masp_lite.viz.meshcat3d.play_to_html(method, scenario, out, seed=..., **overrides)``.

``--set`` works as for ``evaluate``: scenario overrides go to the scenario, other keys to
the method (the 3-D export takes scenario overrides only).
"""
from __future__ import annotations

import importlib
from pathlib import Path

__all__ = ["add_arguments", "run", "play"]


def play(method: str, scenario: str, out, seed: int = 0, overrides=None, method_options=None) -> Path:
    """Record one episode (world 0, seeded by ``seed``) and write it to ``out``; returns the path."""
    from ..envs import get_scenario

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
        try:
            meshcat3d = importlib.import_module("masp_lite.viz.meshcat3d")
        except ModuleNotFoundError as e:
            raise ValueError(f"3-D playback is unavailable ({e}); expected masp_lite.viz.meshcat3d "
                             "and meshcat to be installed, or a .gif/.mp4 output") from None
        out.parent.mkdir(parents=True, exist_ok=True)
        meshcat3d.play_to_html(method, scenario, str(out), seed=seed, **overrides)
        return out
    from ..envs import make
    from ..eval import _factory, _method_params, build_policy
    from .anim2d import animate, record, save

    factory = _factory(method)
    world = make(scenario, num_envs=1, seed=seed, **overrides)
    if "seed" in _method_params(factory)[0]:  # as evaluate does: the seed reaches the method too
        options.setdefault("seed", seed)
    policy = build_policy(factory, method, world, options)
    return save(animate(record(world, policy, seed=seed)), out)


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, help="method name (see masp_lite.methods)")
    parser.add_argument("--scenario", required=True, help="scenario preset, e.g. mpe-20")
    parser.add_argument("--out", required=True, help="output file: .gif, .mp4 (2-D) or .html (3-D)")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override or method option (repeatable)")


def run(args) -> int:
    from ..eval import parse_sets

    overrides, options = parse_sets(args.set, args.method)
    path = play(args.method, args.scenario, args.out, seed=args.seed, overrides=overrides,
                method_options=options)
    print(f"wrote {path}")
    return 0
