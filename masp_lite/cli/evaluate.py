"""``python -m masp_lite evaluate --method M --scenario S [--set KEY=VALUE ...] [--json PATH]``.

Runs :func:`masp_lite.evaluation.evaluate` and prints the record as the paper's table.
``--set`` takes scenario overrides (``num_agents=100``, ``team_after=none``) and the
method's options (``power=2``), each value parsed by the type of what it sets
(:func:`masp_lite.config.parse_sets`, the parser every command uses).
"""
from __future__ import annotations

import json
from pathlib import Path

from ..config import field_types, parse_sets
from ..envs import OVERRIDES, Scenario
from ..evaluation import MAX_ENVS, evaluate, format_table
from ..policies import get_factory, method_options, option_types

__all__ = ["add_arguments", "run", "split_sets", "override_types"]


def override_types() -> dict[str, object]:
    """``{override: type}`` of the scenario overrides (from :class:`~masp_lite.envs.Scenario`'s fields)."""
    types = field_types(Scenario)
    return {k: types[k] for k in OVERRIDES}


def split_sets(items, method: str) -> tuple[dict, dict]:
    """``KEY=VALUE`` strings -> (scenario overrides, method options); a key that is neither fails."""
    factory = get_factory(method)
    _, var_kw = method_options(factory)
    options = option_types(factory)
    targets = {"scenario override": override_types(), f"option of method {method!r}": options}
    if var_kw:  # the method checks the names of its **options itself
        targets[f"option of method {method!r}"] = _Any(options)
    got = parse_sets(items, targets)
    return got["scenario override"], got[f"option of method {method!r}"]


class _Any(dict):
    """Every key is accepted (type unknown): for a factory that takes ``**options``."""

    def __contains__(self, key):
        return True

    def __getitem__(self, key):
        return self.get(key)


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, help="method name (see masp_lite.policies)")
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
    overrides, options = split_sets(args.set, args.method)
    record = evaluate(args.method, args.scenario, episodes=args.episodes, seeds=args.seeds,
                      overrides=overrides, method_options=options, checkpoint=args.checkpoint,
                      device=args.device, num_envs=args.num_envs, progress=True)
    print(format_table([record], fmt=args.format))
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record, indent=2) + "\n")
    return 0
