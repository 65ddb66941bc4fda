"""The parts that turn MASP's networks into an ablation or an RL baseline (chosen by NetConfig).

:class:`~masp_lite.nets.masp.MASPNets` (and :class:`~masp_lite.nets.drones.DroneNets`, in 3-D)
is MASP's Goal Matcher and Coordinated Action Executor; a :class:`~masp_lite.config.NetConfig`
of another method swaps one part:

* the Goal Matcher for an MLP (``goal_matcher="mlp"``, "GM w.o. Graph", :mod:`.ablations`);
* the executor's Group Information Fusion for another view of the team (``executor``:
  ``mlp`` — "CAE w.o. Graph"; ``nearest``, ``subgraph``, ``attention``, ``radius`` — the RL
  baselines', :mod:`.baselines`);
* the goal embedding for attention over every landmark when there are no goals
  (``goal_matcher="none"``: ``mappo``, ``darl1n``).
"""
from __future__ import annotations

from torch import nn

from ..config import NetConfig
from .ablations import FusionMLP, GoalMatcherMLP
from .baselines import AttentionPool, AttentionSubgraph, NearestMLP, RadiusMean

__all__ = ["goal_matcher", "executor_parts"]


def goal_matcher(c: NetConfig, dims: int = 2) -> nn.Module:
    """The "GM w.o. Graph" Goal Matcher (``goal_matcher="mlp"``), built for ``c.team_size`` agents in ``dims`` D."""
    return GoalMatcherMLP(c.width, c.team_size, dims)


def executor_parts(c: NetConfig, pair_features: int, landmark_features: int
                   ) -> tuple[nn.Module | None, nn.Module | None]:
    """``(fusion, goal embedding)`` of ``c``'s executor; ``None`` keeps MASP's part."""
    fusion = {"graph": lambda: None, "mlp": lambda: FusionMLP(pair_features, c.width, c.team_size),
              "nearest": lambda: NearestMLP(pair_features, c.width, c.neighbours_seen),
              "subgraph": lambda: AttentionSubgraph(pair_features, c.width, c.neighbours_seen),
              "attention": lambda: AttentionPool(pair_features, c.width),
              "radius": lambda: RadiusMean(pair_features, c.width)}[c.executor]()
    landmarks = AttentionPool(landmark_features, c.width) if c.goal_matcher == "none" else None  # no goals
    return fusion, landmarks
