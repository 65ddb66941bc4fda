"""The parts that turn MASP's networks into an ablation or an RL baseline (chosen by NetConfig).

:class:`~masp_lite.nets.masp.MASPNets` (and :class:`~masp_lite.nets.drones.DroneNets`, in 3-D)
is MASP's Goal Matcher and Coordinated Action Executor; it asks this module, once when it is
built, for the parts a :class:`~masp_lite.config.NetConfig` of another method swaps, each from
a table keyed by the setting (``None``, or a setting missing from a table, keeps MASP's part):

* the Goal Matcher for an MLP (``goal_matcher="mlp"``, "GM w.o. Graph", :mod:`.ablations`);
* the executor's Group Information Fusion for another view of the team (``executor``:
  ``mlp`` — "CAE w.o. Graph"; ``nearest``, ``subgraph``, ``attention``, ``radius`` — the RL
  baselines', :mod:`.baselines`);
* without goals (``goal_matcher="none"``: ``mappo``, ``darl1n``), the goal input for every
  landmark (:func:`every_landmark`) and the goal embedding for attention over them;
* the executor critic's centralized inputs: ``darl1n``'s (``executor="radius"``) keep only the
  time left (:func:`time_left_only`).

The ``random`` and ``hungarian`` goal sources keep MASP's networks (a never trained, never used
Goal Matcher: every weights file has one layout); their goals are :mod:`masp_lite.algos.goal_sources`'.
"""
from __future__ import annotations

import torch
from torch import nn

from ..config import NetConfig
from .ablations import FusionMLP, GoalMatcherMLP
from .baselines import AttentionPool, AttentionSubgraph, NearestMLP, RadiusMean, landmark_features
from .features import global_features

__all__ = ["check", "goal_matcher", "executor_parts", "goal_view", "critic_inputs", "every_landmark",
           "time_left_only"]


def every_landmark(obs: dict, goals, max_speed: float) -> torch.Tensor:
    """The goal-free executor's goal input: :func:`~masp_lite.nets.baselines.landmark_features` of every
    landmark (B, N, M, 2D + 3); ``goals`` (None: there are none) is ignored."""
    return landmark_features(obs["agent_pos"], obs["agent_vel"], obs["landmark_pos"], obs["covered"], max_speed)


def time_left_only(obs: dict, horizon: int) -> torch.Tensor:
    """``darl1n``'s critic inputs: :func:`~masp_lite.nets.features.global_features` with the team-wide
    fractions zeroed (its value sees the one-hop view and the time left)."""
    extra = global_features(obs, horizon)
    return torch.cat([torch.zeros_like(extra[..., :2]), extra[..., 2:]], dim=-1)


def check(c: NetConfig, owner: str) -> None:
    """An ``mlp`` variant takes a fixed number of agents: it needs ``team_size``."""
    if c.fixed_size and c.team_size < 2:
        raise ValueError(f"{owner}: an mlp variant needs team_size (the agents it is built for), got {c.team_size}")


def goal_matcher(c: NetConfig, dims: int = 2) -> nn.Module | None:
    """The "GM w.o. Graph" Goal Matcher (``goal_matcher="mlp"``), built for ``c.team_size`` agents in ``dims`` D;
    ``None`` keeps MASP's."""
    return GoalMatcherMLP(c.width, c.team_size, dims) if c.goal_matcher == "mlp" else None


def executor_parts(c: NetConfig, pair_features: int, landmark_features: int
                   ) -> tuple[nn.Module | None, nn.Module | None]:
    """``(fusion, goal embedding)`` of ``c``'s executor, built in that order; ``None`` keeps MASP's part."""
    fusion = {"graph": lambda: None, "mlp": lambda: FusionMLP(pair_features, c.width, c.team_size),
              "nearest": lambda: NearestMLP(pair_features, c.width, c.neighbours_seen),
              "subgraph": lambda: AttentionSubgraph(pair_features, c.width, c.neighbours_seen),
              "attention": lambda: AttentionPool(pair_features, c.width),
              "radius": lambda: RadiusMean(pair_features, c.width)}[c.executor]()
    landmarks = AttentionPool(landmark_features, c.width) if c.goal_matcher == "none" else None  # no goals
    return fusion, landmarks


def goal_view(c: NetConfig):
    """``goal(obs, goals, max_speed)``, the executor's goal input, if ``c`` changes it (no goals); else ``None``."""
    return {"none": every_landmark}.get(c.goal_matcher)


def critic_inputs(c: NetConfig):
    """``inputs(obs, horizon)``, the executor critic's centralized inputs, if ``c`` changes them; else ``None``."""
    return {"radius": time_left_only}.get(c.executor)
