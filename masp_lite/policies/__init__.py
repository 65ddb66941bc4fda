"""Every method ``evaluate --method`` accepts: the registry, and the :class:`Policy` protocol.

A *policy* drives a batched world (:class:`~masp_lite.envs.base.BatchedWorld`):

* ``reset(obs) -> None`` — called after ``world.reset()`` with its observation;
* ``act(obs) -> actions`` — the actions for ``world.step``: an integer tensor (B, N) of
  action ids for the particle world, a float tensor (B, N, 4) of motor commands for drones.

Only ``act`` is timed as *decision time* by :mod:`masp_lite.evaluation`. :data:`METHODS`
is the one method table: per world kind, the policy that acts, and for a learned method
its networks' settings and default weights; ``evaluate``, ``train``, ``reproduce`` and the
playground read it. A factory is called as ``factory(world, **options)``; factories are
named by ``"module:attribute"`` strings and imported on first use, so a method's
dependencies (MuJoCo, scipy's spatial code, the networks) load only when it is asked for.
The methods live in this package:
:mod:`.reference` (``random``, ``h-greedy``, ``h-capt``, ``h-bottleneck``), :mod:`.planners` (the "(H)" planners),
:mod:`.drones` and :mod:`.drone_planners` (the drone versions of ``h-greedy`` and of the (H) planners)
and :mod:`.masp` (``masp``, its ablations ``masp-rg``,
``gm-mlp``, ``cae-mlp``, and the RL baselines ``h-mappo``, ``htamp``, ``mage-x``, ``mappo``, ``darl1n``)
and :mod:`.drone_masp` (``masp``, ``masp-velocity`` and the RL baselines on drones);
:mod:`.goal_sources` says where a drone planner's goals come from (its Hungarian assignment, or a
trained Goal Matcher: ``goals="masp"``).
"""
from __future__ import annotations

import functools
import importlib
import inspect
import typing
from typing import Protocol

import torch

from ..envs import OVERRIDES

__all__ = ["Policy", "METHODS", "make_policy", "method_names", "method_entry", "learned_methods", "get_factory",
           "method_options", "option_types", "build_policy"]


class Policy(Protocol):
    """What :func:`masp_lite.evaluation.rollout` needs from a method."""

    def reset(self, obs: dict) -> None:
        """Forget the last episode; ``obs`` is the first observation of the new one."""

    def act(self, obs: dict) -> torch.Tensor:
        """The actions of every alive agent of every world."""


_GRAPH = {"goal_matcher": "graph", "executor": "graph"}
_TEAM_SIZES = ("mpe-5", "mpe-20", "mpe-50")
_DRONE_SIZES = ("drone-5", "drone-20")


def _learned(group: str, goal_matcher: str, executor: str, weights: tuple, kind: str = "particle") -> dict:
    nets = {"goal_matcher": goal_matcher, "executor": executor}
    if kind == "drone":  # the paper's drone action: a throttle command per motor
        nets["action"] = "throttle"
    return {"policy": "drone_masp:DroneMASPPolicy" if kind == "drone" else "masp:MASPPolicy", "group": group,
            "nets": nets, "weights": weights}


def _baseline(goal_matcher: str, executor: str, train: dict | None = None) -> dict:
    """An RL baseline's entries: trained from scratch on each particle preset, and on drone-5 then drone-20,
    with packaged weights for each."""
    extra = {"train": train} if train else {}
    return {"particle": {**_learned("baseline", goal_matcher, executor, _TEAM_SIZES), **extra},
            "drone": {**_learned("baseline", goal_matcher, executor, _DRONE_SIZES, "drone"), **extra}}


#: The one method table (data): name -> world kind -> ``policy`` (``"module:attribute"`` in this
#: package, imported on first use) and, for a learned method, ``nets`` (the ``NetConfig`` settings its
#: weights must have; training starts from them), ``group`` (``ablation`` or ``baseline``, the paper's
#: tables), ``train`` (further training settings) and
#: ``weights``: ``"shipped"`` (one file per preset, ``masp_lite/weights/manifest.json``) or the presets
#: whose seed-0 weights ship as package data (``masp_lite/weights/methods/``, :func:`masp_lite.weights.
#: method_checkpoint`; until they do, ``checkpoint=PATH`` names them). A method missing a world kind refuses it,
#: naming the kinds it has. ``group`` ``beyond``: a method past the paper's (``masp-minmax``).
METHODS: dict[str, dict[str, dict]] = {
    "random": {"particle": {"policy": "reference:RandomPolicy"}, "drone": {"policy": "reference:RandomPolicy"}},
    "h-greedy": {"particle": {"policy": "reference:HungarianGreedy"},
                 "drone": {"policy": "drones:DroneHungarianGreedy"}},
    "h-capt": {"particle": {"policy": "reference:capt"}},
    "h-bottleneck": {"particle": {"policy": "reference:min_max"},
                     "drone": {"policy": "drone_planners:DroneBottleneck"}},
    "h-orca": {"particle": {"policy": "planners:HOrca"}, "drone": {"policy": "drone_planners:DroneHOrca"}},
    "h-rrtstar": {"particle": {"policy": "planners:HRRTStar"}, "drone": {"policy": "drone_planners:DroneHRRTStar"}},
    "h-voronoi": {"particle": {"policy": "planners:HVoronoi"}, "drone": {"policy": "drone_planners:DroneHVoronoi"}},
    "masp": {"particle": {"policy": "masp:MASPPolicy", "nets": _GRAPH, "weights": "shipped"},
             "drone": {"policy": "drone_masp:DroneMASPPolicy", "nets": {"executor": "graph", "action": "throttle"},
                       "weights": "shipped"}},
    "masp-velocity": {"drone": {"policy": "drone_masp:DroneMASPPolicy",
                                "nets": {"executor": "graph", "action": "velocity"}, "weights": _DRONE_SIZES}},
    # beyond the paper: MASP's networks and executor, its Goal Matcher taught h-bottleneck's min-max assignment by
    # imitation (masp_lite.algos.imitation; the recipe masp-minmax); mpe-50's weights also run mpe-50to20
    "masp-minmax": {"particle": {"policy": "masp:MASPPolicy", "nets": _GRAPH, "group": "beyond",
                                 "weights": _TEAM_SIZES}},
    # the paper's ablations (trained on mpe-20)
    "masp-rg": {"particle": _learned("ablation", "random", "graph", ("mpe-20",))},
    "gm-mlp": {"particle": _learned("ablation", "mlp", "graph", ("mpe-20",))},
    "cae-mlp": {"particle": _learned("ablation", "graph", "mlp", ("mpe-20",))},
    # the RL baselines (section "Baselines", masp_lite.nets.baselines)
    "h-mappo": _baseline("hungarian", "nearest"),
    "htamp": _baseline("mlp", "mlp"),
    "mage-x": _baseline("graph", "subgraph", {"global_step": 1000}),  # goals once, at the start (past every horizon)
    "mappo": _baseline("none", "attention"),
    "darl1n": _baseline("none", "radius"),
}


def method_names(kind: str | None = None) -> list[str]:
    """Every method name, or those with a policy for world ``kind`` (``"particle"``, ``"drone"``)."""
    return sorted(m for m, e in METHODS.items() if kind is None or kind in e)


def method_entry(name: str, kind: str | None = None) -> dict:
    """The table's entry of method ``name`` for world ``kind`` (default: its first kind); one clear error."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {method_names()}")
    kinds = METHODS[name]
    kind = next(iter(kinds)) if kind is None else kind
    if kind not in kinds:
        raise ValueError(f"{name}: no policy for {kind} worlds; expected a {' or '.join(kinds)} scenario "
                         f"({kind} methods: {method_names(kind)})")
    return kinds[kind]


def learned_methods(kind: str = "particle") -> dict[str, dict]:
    """``{method: entry}`` of the methods with networks (``nets``) for world ``kind``."""
    return {m: e[kind] for m, e in METHODS.items() if kind in e and "nets" in e[kind]}


def get_factory(name: str, kind: str | None = None):
    """The class or function that builds method ``name``'s policy for world ``kind`` (imported now).

    A learned method's factory is its policy class with ``method=name`` bound."""
    entry = method_entry(name, kind)
    module_name, attr = entry["policy"].split(":")
    target = getattr(importlib.import_module(f"{__name__}.{module_name}"), attr)
    return functools.partial(target, method=name) if "nets" in entry else target


def _parameters(factory):
    bound = set(factory.keywords) if isinstance(factory, functools.partial) else set()
    factory = factory.func if isinstance(factory, functools.partial) else factory
    target = factory.__init__ if inspect.isclass(factory) else factory
    params = list(inspect.signature(target).parameters.values())
    if inspect.isclass(factory):
        params = params[1:]  # self
    return target, [p for p in params[1:] if p.name not in bound]  # the world; the method (bound)


def method_options(factory) -> tuple[set[str], bool]:
    """Named options a factory accepts (besides the world) and whether it takes ``**options``."""
    _, params = _parameters(factory)
    named = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return named, any(p.kind == p.VAR_KEYWORD for p in params)


def option_types(factory) -> dict[str, object]:
    """``{option: annotated type or None}`` of a factory's named options (for ``--set`` parsing)."""
    target, params = _parameters(factory)
    hints = typing.get_type_hints(target)
    return {p.name: hints.get(p.name) for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def build_policy(factory, method: str, world, options: dict):
    """``factory(world, **options)``, with a wrong option reported as one ValueError.

    For a method of the table, the factory of the world's kind is used.

    A misspelt key may have been meant for the scenario: when the method rejects a key it
    does not name (unknown, or refused by a factory that takes ``**options``), the message
    also lists the scenario overrides, so both lists show. Errors about the value of an
    option the method does name (a bad ``checkpoint`` file, ``global_step=0``) pass unchanged.
    """
    kind = getattr(getattr(world, "scenario", None), "kind", None)
    if method in METHODS and kind is not None:  # the policy of the world's kind
        factory = get_factory(method, kind)
    named, var_kw = method_options(factory)
    also = f"; scenario overrides are {sorted(OVERRIDES)}"
    bad = sorted(k for k in options if k not in named and not var_kw)
    if bad:
        raise ValueError(f"method {method!r}: unknown option(s) {bad}; expected one of {sorted(named)}{also}")
    try:
        return factory(world, **options)
    except TypeError as e:
        raise ValueError(f"method {method!r}: bad option(s) {sorted(options)} ({e}){also}") from None
    except ValueError as e:
        if any(k in str(e) for k in options if k not in named):
            raise ValueError(f"{e}{also}") from None
        raise


def make_policy(name: str, world, **options):
    """Build the policy called ``name`` for ``world`` (its world kind's; options are method-specific)."""
    return build_policy(get_factory(name, world.scenario.kind), name, world, options)
