"""Every method ``evaluate --method`` accepts: the registry, and the :class:`Policy` protocol.

A *policy* drives a batched world (:class:`~masp_lite.envs.base.BatchedWorld`):

* ``reset(obs) -> None`` — called after ``world.reset()`` with its observation;
* ``act(obs) -> actions`` — the actions for ``world.step``: an integer tensor (B, N) of
  action ids for the particle world, a float tensor (B, N, 4) of motor commands for drones.

Only ``act`` is timed as *decision time* by :mod:`masp_lite.evaluation`. A factory is
called as ``factory(world, **options)``; factories are named by ``"module:attribute"``
strings and imported on first use, so a method's dependencies (MuJoCo, scipy's spatial
code, the networks) load only when it is asked for. The methods live in this package:
:mod:`.reference` (``random``, ``h-greedy``, ``h-capt``, ``h-bottleneck``), :mod:`.planners` (the "(H)" planners),
:mod:`.drones` and :mod:`.drone_planners` (the drone versions of ``h-greedy`` and of the (H) planners)
and :mod:`.masp` (``masp``, its ablations ``masp-rg``,
``gm-mlp``, ``cae-mlp``, and the RL baselines ``h-mappo``, ``htamp``, ``mage-x``, ``mappo``, ``darl1n``).
"""
from __future__ import annotations

import importlib
import inspect
import typing
from typing import Protocol

import torch

from ..envs import OVERRIDES

__all__ = ["Policy", "METHODS", "make_policy", "method_names", "get_factory", "method_options", "option_types",
           "build_policy"]


class Policy(Protocol):
    """What :func:`masp_lite.evaluation.rollout` needs from a method."""

    def reset(self, obs: dict) -> None:
        """Forget the last episode; ``obs`` is the first observation of the new one."""

    def act(self, obs: dict) -> torch.Tensor:
        """The actions of every alive agent of every world."""


METHODS: dict[str, str] = {
    "random": "masp_lite.policies.reference:RandomPolicy",
    "h-greedy": "masp_lite.policies.reference:HungarianGreedy",
    "h-capt": "masp_lite.policies.reference:capt",
    "h-bottleneck": "masp_lite.policies.reference:min_max",
    "h-orca": "masp_lite.policies.planners:HOrca",
    "h-rrtstar": "masp_lite.policies.planners:HRRTStar",
    "h-voronoi": "masp_lite.policies.planners:HVoronoi",
    "masp": "masp_lite.policies.masp:MASPPolicy",
    "masp-velocity": "masp_lite.policies.drone_masp:DroneMASPVelocity",
    "masp-rg": "masp_lite.policies.masp:masp_rg",
    "gm-mlp": "masp_lite.policies.masp:gm_mlp",
    "cae-mlp": "masp_lite.policies.masp:cae_mlp",
    "h-mappo": "masp_lite.policies.masp:h_mappo",
    "htamp": "masp_lite.policies.masp:htamp",
    "mage-x": "masp_lite.policies.masp:mage_x",
    "mappo": "masp_lite.policies.masp:mappo",
    "darl1n": "masp_lite.policies.masp:darl1n",
}


def method_names() -> list[str]:
    return sorted(METHODS)


def get_factory(name: str):
    """The class or function that builds method ``name``'s policy (imported now)."""
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; expected one of {method_names()}")
    module_name, attr = METHODS[name].split(":")
    return getattr(importlib.import_module(module_name), attr)


def _parameters(factory):
    target = factory.__init__ if inspect.isclass(factory) else factory
    params = list(inspect.signature(target).parameters.values())
    if inspect.isclass(factory):
        params = params[1:]  # self
    return target, params[1:]  # the world


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

    A misspelt key may have been meant for the scenario: when the method rejects a key it
    does not name (unknown, or refused by a factory that takes ``**options``), the message
    also lists the scenario overrides, so both lists show. Errors about the value of an
    option the method does name (a bad ``checkpoint`` file, ``global_step=0``) pass unchanged.
    """
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
    """Build the policy called ``name`` for ``world`` (options are method-specific)."""
    return build_policy(get_factory(name), name, world, options)
