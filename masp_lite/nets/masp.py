"""MASP's networks: the two actors and their centralized critics, for particles and drones alike.

* :class:`GoalMatcher` (high level, section "Goal Matcher"): agent graph and goal graph
  (fully connected, edges 1) -> embeddings (Linear + ReLU to ``L``) -> one
  :class:`~masp_lite.nets.encoders.SelfEncoder` per graph -> :class:`~masp_lite.nets.encoders.CrossEncoder`
  -> per-agent logits over goals. Nodes hold map-normalised positions and velocities (agents) or
  positions and a covered flag (goals), plus nearest distances; the Cross-Encoder's distance ``D``
  comes with a second channel, ``D_kj - min_i D_ij`` (how much farther ``k`` is than the closest
  agent), so one network serves every map size. The graphs are the same for every agent, so they
  are encoded once per world; only the Cross-Encoder is per agent. Dropped agents are masked out.
* :class:`CoordinatedActionExecutor` (low level, section "Coordinated Action Executor"):
  :class:`~masp_lite.nets.fusion.GroupInformationFusion` over the pair features, plus the
  goal embedding (MLP over the assigned goal's features), plus an obstacle embedding, -> MLP
  -> logits over the 5 MPE actions. **Obstacles** (which the paper's description of the
  executor does not mention) are the ``obstacles_seen`` nearest ones, embedded by an MLP.
* Critics (CTDE: centralized training, decentralized execution): :class:`GoalMatcherCritic`
  pools the whole agent and goal graphs; :class:`ExecutorCritic` reads the executor's
  features (gradient stopped) and global inputs (landmarks covered and reached, time left).
* :class:`MASPNets`: the four, from a :class:`~masp_lite.config.NetConfig`, and the calls that
  training and the policies make on an observation; the drones' networks
  (:class:`~masp_lite.nets.drones.DroneNets`) are this class with only what differs.

What each input holds is :mod:`masp_lite.nets.features`'. All parameters are shared by the
agents and every weight acts per node, pair or group, so the networks run for any team size.
An ablation or an RL baseline swaps parts, chosen by :mod:`masp_lite.nets.variants`.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import torch
from torch import nn

from ..config import NetConfig
from ..envs.particle import NUM_ACTIONS
from . import features
from .encoders import CrossEncoder, SelfEncoder, mlp
from .features import assigned_goal_features, global_features, gm_inputs, obstacle_features, pair_features
from .fusion import GroupInformationFusion, group_division

__all__ = ["GoalMatcher", "GoalMatcherCritic", "CoordinatedActionExecutor", "ExecutorCritic", "ExecutorInputs",
           "MASPNets"]

PAIR_FEATURES, GOAL_FEATURES, OBSTACLE_FEATURES, GLOBAL_FEATURES, LANDMARK_FEATURES = 6, 6, 3, 3, 7


class ExecutorInputs(NamedTuple):
    """The particle executor's inputs for one step (a tuple too: ``executor(*inputs)``); :mod:`.features`."""

    pair: torch.Tensor       # (B, N, N, 6) pair_features
    groups: torch.Tensor     # (B, N, G, n) group_division (long)
    alive: torch.Tensor      # (B, N)
    goal: torch.Tensor       # (B, N, 6) the assigned goal's; (B, N, M, 7) every landmark's without goals
    obstacles: torch.Tensor  # (B, N, 3 * obstacles_seen) obstacle_features


class _GraphEncoders(nn.Module):
    def __init__(self, width: int, dims: int = 2):
        super().__init__()
        self.embed_agent = mlp([2 * dims + 1, width], last_activation=True)
        self.embed_goal = mlp([dims + 2, width], last_activation=True)
        self.agent_encoder = SelfEncoder(width)
        self.goal_encoder = SelfEncoder(width)

    def encode(self, agent_x, goal_x, alive):
        ya, _ = self.agent_encoder(self.embed_agent(agent_x), alive)
        yt, _ = self.goal_encoder(self.embed_goal(goal_x))
        return ya, yt


class GoalMatcher(_GraphEncoders):
    """High-level actor: ``forward(agent_x, goal_x, dist, alive) -> logits`` (B, N, M).

    Agent ``k``'s categorical over goals is ``softmax(logits[:, k])`` = ``S_intra^k``
    (eq. 4). :mod:`masp_lite.nets.decoding` turns the scores into goals: by default the
    most likely assignment of distinct goals at evaluation, a sequential draw of distinct
    goals in training.
    """

    def __init__(self, width: int = 32, dims: int = 2):
        super().__init__(width, dims)
        self.cross = CrossEncoder(width, distance_channels=2)

    def forward(self, agent_x, goal_x, dist, alive, goal_mask=None):
        ya, yt = self.encode(agent_x, goal_x, alive)
        return self.cross(ya, yt, dist, goal_mask)


class GoalMatcherCritic(_GraphEncoders):
    """Centralized high-level critic: ``forward(agent_x, goal_x, alive, extra) -> (B, N)``.

    Agent ``k``'s value reads its own encoded node, the mean of the alive agents' nodes,
    the mean of the goal nodes and the global inputs (:func:`~masp_lite.nets.features.global_features`).
    """

    def __init__(self, width: int = 32, dims: int = 2):
        super().__init__(width, dims)
        self.head = mlp([3 * width + GLOBAL_FEATURES, width, 1])

    def forward(self, agent_x, goal_x, alive, extra):
        ya, yt = self.encode(agent_x, goal_x, alive)
        w = alive.to(ya.dtype).unsqueeze(-1)
        pooled = (ya * w).sum(1, keepdim=True) / w.sum(1, keepdim=True).clamp(min=1)
        x = torch.cat([ya, pooled.expand_as(ya), yt.mean(1, keepdim=True).expand_as(ya), extra], dim=-1)
        return self.head(x).squeeze(-1)


class CoordinatedActionExecutor(nn.Module):
    """Low-level actor: ``forward(*inputs) -> logits`` (B, N, 5), ``inputs`` an
    :class:`~masp_lite.nets.features.ExecutorInputs`."""

    def __init__(self, width: int = 32, gcn_layers: int = 1, obstacles_seen: int = 2, fusion: nn.Module | None = None,
                 goal_embed: nn.Module | None = None):
        super().__init__()
        self.fusion = GroupInformationFusion(PAIR_FEATURES, width, gcn_layers) if fusion is None else fusion
        self.goal_embed = mlp([GOAL_FEATURES, width], last_activation=True) if goal_embed is None else goal_embed
        self.obstacle_embed = mlp([OBSTACLE_FEATURES * obstacles_seen, width], last_activation=True)
        self.head = mlp([3 * width, width, width, NUM_ACTIONS])

    def features(self, pair, groups, alive, goal, obstacles) -> list:
        """The three features the head (and the critic) read: fusion, goal, obstacles, each (B, N, width)."""
        return [self.fusion(pair, groups, alive), self.goal_embed(goal), self.obstacle_embed(obstacles)]

    def output(self, features: list) -> torch.Tensor:
        return self.head(torch.cat(features, dim=-1))

    def forward(self, pair, groups, alive, goal, obstacles):
        return self.output(self.features(pair, groups, alive, goal, obstacles))


class ExecutorCritic(nn.Module):
    """Centralized low-level critic -> (B, N).

    It reads the executor's three features (fusion, goal, obstacle or flight state) with the
    gradient stopped, plus the global inputs; sharing the fusion halves the training cost (the
    Group Information Fusion dominates it) and the actor's loss alone shapes it.
    """

    def __init__(self, width: int = 32):
        super().__init__()
        self.head = mlp([3 * width + GLOBAL_FEATURES, width, width, 1])

    def forward(self, features: list, extra):
        return self.head(torch.cat([f.detach() for f in features] + [extra], dim=-1)).squeeze(-1)


class MASPNets(nn.Module):
    """Both levels' actors and critics, built from a :class:`~masp_lite.config.NetConfig`.

    ``MASPNets(NetConfig(width=32, ...))`` or ``MASPNets(width=32, ...)``; ``arch`` is the
    configuration as a dict, the form weights files store (:mod:`masp_lite.weights`).

    The particle world's networks. A world differs only in the class attributes below (its
    dimensions, sensing radius, speed scale and feature widths), its executor
    (:meth:`build_executor`) and the executor's own input beside the team and the goal
    (:meth:`own_features`): :class:`~masp_lite.nets.drones.DroneNets` sets those for drones.
    """

    world, dims, sense, max_speed = "particle", 2, features.SENSE, features.MAX_SPEED
    pair_size, landmark_size = PAIR_FEATURES, LANDMARK_FEATURES
    inputs_type = ExecutorInputs  # the executor's inputs, by name

    def __init__(self, config: NetConfig | None = None, **arch):
        super().__init__()
        from . import variants  # an ablation's or a baseline's parts, beside the paper's path
        self.config = c = self._config(config, arch)
        variants.check(c, type(self).__name__)
        gm = variants.goal_matcher(c, self.dims)  # built in this order: a seed gives the same initial weights
        self.gm = GoalMatcher(c.width, self.dims) if gm is None else gm
        self.gm_critic = GoalMatcherCritic(c.width, self.dims)
        self.cae = self.build_executor(c, *variants.executor_parts(c, self.pair_size, self.landmark_size))
        self.cae_critic = ExecutorCritic(c.width)
        self.goal_inputs = variants.goal_view(c) or assigned_goal_features  # (obs, goals, max_speed): the goal input
        self.critic_inputs = variants.critic_inputs(c) or global_features  # (obs, horizon): the critic's centralized

    def _config(self, config: NetConfig | None, arch: dict) -> NetConfig:
        name = type(self).__name__
        if config is not None and arch:
            raise ValueError(f"{name}: expected a NetConfig or keyword settings, not both")
        try:
            c = config if config is not None else NetConfig(**arch)
        except TypeError as e:
            raise ValueError(f"{name}: {e}; expected settings among {sorted(NetConfig.__dataclass_fields__)}") \
                from None
        if c.world != self.world:
            raise ValueError(f"{name}: action {c.action!r} is for {c.world} worlds; expected a {self.world} world's "
                             "action (discrete for particles, throttle or velocity for drones)")
        return c

    def build_executor(self, c: NetConfig, fusion: nn.Module | None, goal_embed: nn.Module | None) -> nn.Module:
        """The world's executor; ``fusion`` and ``goal_embed`` replace its own when given (a variant's)."""
        return CoordinatedActionExecutor(c.width, c.gcn_layers, c.obstacles_seen, fusion, goal_embed)

    def own_features(self, obs: dict) -> torch.Tensor:
        """The executor's input beside the team and the goal: the nearest obstacles."""
        return obstacle_features(obs["agent_pos"], obs["obstacle_pos"], self.config.obstacles_seen)

    @property
    def arch(self) -> dict:
        """The architecture as a plain dict (``NetConfig``'s fields)."""
        return dataclasses.asdict(self.config)

    # ------------------------------------------------------------------ Goal Matcher
    def gm_logits(self, obs: dict, scale: float, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
        a, g, dist = gm_inputs(obs, scale, self.max_speed)
        return self.gm(a, g, dist, obs["alive"], goal_mask)

    def gm_value(self, obs: dict, scale: float, horizon: int) -> torch.Tensor:
        a, g, _ = gm_inputs(obs, scale, self.max_speed)
        return self.gm_critic(a, g, obs["alive"], global_features(obs, horizon))

    def gm_forward(self, obs: dict, scale: float, horizon: int) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`gm_logits` and :meth:`gm_value` from one :func:`~masp_lite.nets.features.gm_inputs`
        (what training calls)."""
        a, g, dist = gm_inputs(obs, scale, self.max_speed)
        return self.gm(a, g, dist, obs["alive"]), self.gm_critic(a, g, obs["alive"], global_features(obs, horizon))

    # ------------------------------------------------------------------ executor
    def cae_inputs(self, obs: dict, goals: torch.Tensor | None, perm: torch.Tensor):
        """The executor's inputs (:attr:`inputs_type`) for goal indices ``goals`` (B, N) and random group order
        ``perm`` (B, N); ``goals`` None for the goal-free baselines (their goal input is every landmark)."""
        pos, vel = obs["agent_pos"], obs["agent_vel"]
        goal = self.goal_inputs(obs, goals, self.max_speed)
        return self.inputs_type(pair_features(pos, vel, self.sense, self.max_speed),
                                group_division(perm, self.config.group_size), obs["alive"], goal,
                                self.own_features(obs))

    def cae_logits(self, inputs):
        """The executor's output: logits (B, N, 5) for particles, ``(mean, log_std)`` for drones."""
        return self.cae(*inputs)

    def cae_forward(self, inputs, obs: dict, horizon: int):
        """The executor's output (:meth:`cae_logits`) and the critic's values (B, N) from one pass of the fusion."""
        feats = self.cae.features(*inputs)
        return self.cae.output(feats), self.cae_critic(feats, self.critic_inputs(obs, horizon))
