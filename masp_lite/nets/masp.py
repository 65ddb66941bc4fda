"""MASP's networks: the two actors, their centralized critics, and what they observe.

* :class:`GoalMatcher` (high level, section "Goal Matcher"): agent graph and goal graph
  (fully connected, edges 1) -> embeddings (Linear + ReLU to ``L``) -> one
  :class:`~masp_lite.nets.encoders.SelfEncoder` per graph -> :class:`~masp_lite.nets.encoders.CrossEncoder`
  -> per-agent logits over goals. Nodes hold map-normalised positions (``pos / (world_size/2)``)
  and velocities (agents) or positions and a covered flag (goals), plus nearest distances
  (:func:`gm_inputs`); the Cross-Encoder's distance ``D`` is normalised the same way and
  comes with a second channel, ``D_kj - min_i D_ij`` (how much farther ``k`` is than the
  closest agent), so one network serves every map size.
  The graphs are the same for every agent, so they are encoded once per world; only
  the Cross-Encoder is per agent. Dropped agents are masked out of the agent graph.
* :class:`CoordinatedActionExecutor` (low level, section "Coordinated Action Executor"):
  :class:`~masp_lite.nets.fusion.GroupInformationFusion` over :func:`pair_features`, plus
  the goal embedding (MLP over :func:`goal_features` of the assigned goal), plus an
  obstacle embedding, -> MLP -> logits over the 5 MPE actions. **Obstacles** (which the
  paper's description of the executor does not mention) are seen as the relative
  positions of the ``obstacles_seen`` nearest obstacles (:func:`obstacle_features`,
  clipped at ``SENSE`` metres and padded when there are fewer), embedded by an MLP and
  concatenated with the fusion feature and the goal embedding before the final MLP.
* Critics (CTDE: centralized training, decentralized execution): :class:`GoalMatcherCritic`
  pools the whole agent and goal graphs; :class:`ExecutorCritic` reads the executor's
  features (gradient stopped) and global inputs (:func:`global_features`: fractions of
  landmarks covered and reached, time left). Only the actors are needed to act.

All parameters are shared by the agents and every weight acts per node, pair or group,
so the networks run for any team size (the ablations' MLPs, :mod:`masp_lite.nets.ablations`,
chosen by :class:`~masp_lite.config.NetConfig`, are the exception). The RL baselines' executors
(:mod:`masp_lite.nets.baselines`) replace only the fusion. Executor inputs are in metres (MPE's dynamics do
not scale with the map); relative vectors are clipped at ``SENSE`` = 1 m for neighbours
and obstacles (collisions happen below 0.2 m).
"""
from __future__ import annotations

import dataclasses

import torch
from torch import nn

from ..config import NetConfig
from ..envs.particle import NUM_ACTIONS
from .encoders import CrossEncoder, SelfEncoder, mlp
from .fusion import GroupInformationFusion, group_division

__all__ = ["GoalMatcher", "GoalMatcherCritic", "CoordinatedActionExecutor", "ExecutorCritic",
           "pair_features", "goal_features", "obstacle_features", "global_features",
           "critic_extra", "gm_inputs", "GoalMatcherCalls", "MASPNets", "MAX_SPEED", "SENSE"]

MAX_SPEED = 2.0
"""MPE's terminal speed under a constant action (m/s); velocities are divided by it."""
SENSE = 1.0
"""Metres at which neighbour and obstacle vectors are clipped."""

PAIR_FEATURES, GOAL_FEATURES, OBSTACLE_FEATURES, GLOBAL_FEATURES, LANDMARK_FEATURES = 6, 6, 3, 3, 7


def _clip(rel: torch.Tensor, radius: float) -> tuple[torch.Tensor, torch.Tensor]:
    d = rel.norm(dim=-1, keepdim=True)
    return rel * (radius / d.clamp(min=radius)), d


def pair_features(pos: torch.Tensor, vel: torch.Tensor, sense: float = SENSE, max_speed: float = MAX_SPEED
                  ) -> torch.Tensor:
    """(B, N, N, 2D + 2): agent ``j`` seen from agent ``k`` at ``[b, k, j]``, in D = 2 or 3 dimensions.

    ``[rel / sense (D, clipped to norm 1), min(dist, sense) / sense, (v_j - v_k) / max_speed (D),
    is_self]``; the drones pass their own ``sense`` and ``max_speed`` (:mod:`masp_lite.nets.drones`).
    """
    rel, d = _clip(pos.unsqueeze(1) - pos.unsqueeze(2), sense)
    dv = (vel.unsqueeze(1) - vel.unsqueeze(2)) / max_speed
    N = pos.shape[1]
    eye = torch.eye(N, dtype=pos.dtype, device=pos.device).expand(*pos.shape[:1], N, N).unsqueeze(-1)
    return torch.cat([rel / sense, d.clamp(max=sense) / sense, dv, eye], dim=-1)


def goal_features(pos: torch.Tensor, vel: torch.Tensor, goal_pos: torch.Tensor, max_speed: float = MAX_SPEED
                  ) -> torch.Tensor:
    """(B, N, 2D + 2): each agent's assigned goal ``goal_pos`` (B, N, D) seen from the agent.

    ``[unit direction (D), min(dist, 1 m), log(1 + dist), own velocity / max_speed (D)]``.
    """
    rel = goal_pos - pos
    d = rel.norm(dim=-1, keepdim=True)
    unit = rel / d.clamp(min=1e-6)
    return torch.cat([unit, d.clamp(max=1.0), torch.log1p(d), vel / max_speed], dim=-1)


def obstacle_features(pos: torch.Tensor, obstacle_pos: torch.Tensor, count: int) -> torch.Tensor:
    """(B, N, 3 * count): the ``count`` nearest obstacles, nearest first.

    Each is ``[rel / SENSE (clipped to norm 1), min(dist, SENSE) / SENSE]``; missing ones
    (fewer than ``count`` obstacles) read ``[0, 0, 1]``, an obstacle at the sensing edge.
    """
    B, N = pos.shape[:2]
    K = obstacle_pos.shape[1]
    pad = torch.tensor([0.0, 0.0, 1.0], dtype=pos.dtype, device=pos.device)
    if K == 0:
        return pad.repeat(B, N, count)
    rel = obstacle_pos.unsqueeze(1) - pos.unsqueeze(2)                  # (B, N, K, 2)
    d = rel.norm(dim=-1)
    k = min(count, K)
    d_near, idx = d.topk(k, dim=-1, largest=False)
    rel_near = torch.gather(rel, 2, idx.unsqueeze(-1).expand(B, N, k, 2))
    rel_c, _ = _clip(rel_near, SENSE)
    feats = torch.cat([rel_c / SENSE, d_near.clamp(max=SENSE).unsqueeze(-1) / SENSE], dim=-1)
    if k < count:
        feats = torch.cat([feats, pad.expand(B, N, count - k, 3)], dim=2)
    return feats.reshape(B, N, 3 * count)


def global_features(obs: dict, horizon: int) -> torch.Tensor:
    """(B, N, 3) centralized inputs for the critics: landmarks covered now, ever reached, time left."""
    cov = obs["covered"].to(obs["agent_pos"].dtype).mean(-1, keepdim=True)
    rea = obs["reached"].to(cov.dtype).mean(-1, keepdim=True)
    left = 1.0 - obs["t"].to(cov.dtype).unsqueeze(-1) / horizon
    return torch.cat([cov, rea, left], dim=-1).unsqueeze(1).expand(-1, obs["alive"].shape[1], -1)


def critic_extra(config: NetConfig, obs: dict, horizon: int) -> torch.Tensor:
    """The executor critic's centralized inputs: :func:`global_features`, of which ``darl1n``'s
    (``executor="radius"``) keeps only the time left (its value sees the one-hop view and the time)."""
    extra = global_features(obs, horizon)
    if config.executor == "radius":
        extra = torch.cat([torch.zeros_like(extra[..., :2]), extra[..., 2:]], dim=-1)
    return extra


def gm_inputs(obs: dict, scale: float, max_speed: float = MAX_SPEED):
    """Goal Matcher inputs: agent nodes (B, N, 2D + 1), goal nodes (B, M, D + 2), pair distances (B, N, M, 2).

    Pair ``(k, j)``: ``[D_kj, D_kj - min_i D_ij]`` — the L2 distance of eq. 4 and how much
    farther agent ``k`` is from goal ``j`` than the closest alive agent (0 when ``k`` is
    the closest).

    Agent node: ``[pos / scale (D), vel / max_speed (D), distance to its nearest goal / scale]``;
    goal node: ``[pos / scale (D), covered, distance to its nearest alive agent / scale]``
    (``scale = world_size / 2``). The two nearest-distances are position information the
    paper's nodes carry implicitly; giving them explicitly lets agent ``k`` compare its own
    distance ``D_kj`` with the closest competitor's, which speeds up learning to avoid
    picking the same goal as another agent.
    """
    dist = torch.cdist(obs["agent_pos"], obs["landmark_pos"]) / scale
    alive = obs["alive"]
    near_goal = dist.min(-1).values.unsqueeze(-1)
    big = torch.finfo(dist.dtype).max
    near_agent = dist.masked_fill(~alive.unsqueeze(-1), big).min(1).values.clamp(max=4.0).unsqueeze(-1)
    a = torch.cat([obs["agent_pos"] / scale, obs["agent_vel"] / max_speed, near_goal], dim=-1)
    g = torch.cat([obs["landmark_pos"] / scale, obs["covered"].to(a.dtype).unsqueeze(-1), near_agent], dim=-1)
    margin = (dist - near_agent.transpose(1, 2)).clamp(min=0.0, max=4.0)
    return a, g, torch.stack([dist, margin], dim=-1)


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
    the mean of the goal nodes and :func:`global_features`.
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
    """Low-level actor: ``forward(pair, groups, alive, goal_f, obstacle_f) -> logits`` (B, N, 5)."""

    def __init__(self, width: int = 32, gcn_layers: int = 1, obstacles_seen: int = 2, fusion: nn.Module | None = None,
                 goal_embed: nn.Module | None = None):
        super().__init__()
        self.fusion = GroupInformationFusion(PAIR_FEATURES, width, gcn_layers) if fusion is None else fusion
        self.goal_embed = mlp([GOAL_FEATURES, width], last_activation=True) if goal_embed is None else goal_embed
        self.obstacle_embed = mlp([OBSTACLE_FEATURES * obstacles_seen, width], last_activation=True)
        self.head = mlp([3 * width, width, width, NUM_ACTIONS])

    def features(self, pair, groups, alive, goal_f, obstacle_f):
        return [self.fusion(pair, groups, alive), self.goal_embed(goal_f), self.obstacle_embed(obstacle_f)]

    def forward(self, pair, groups, alive, goal_f, obstacle_f):
        return self.head(torch.cat(self.features(pair, groups, alive, goal_f, obstacle_f), dim=-1))


class ExecutorCritic(nn.Module):
    """Centralized low-level critic -> (B, N).

    It reads the executor's three features (fusion, goal, obstacle) with the gradient
    stopped, plus :func:`global_features`; sharing the fusion halves the training cost
    (the Group Information Fusion dominates it) and the actor's loss alone shapes it.
    """

    def __init__(self, width: int = 32):
        super().__init__()
        self.head = mlp([3 * width + GLOBAL_FEATURES, width, width, 1])

    def forward(self, features: list, extra):
        return self.head(torch.cat([f.detach() for f in features] + [extra], dim=-1)).squeeze(-1)


class GoalMatcherCalls:
    """The Goal Matcher's calls on an observation, shared by :class:`MASPNets` and the drones' ``DroneNets``
    (which set ``max_speed``): each builds :func:`gm_inputs` once."""

    max_speed = MAX_SPEED

    def gm_logits(self, obs: dict, scale: float, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
        a, g, dist = gm_inputs(obs, scale, self.max_speed)
        return self.gm(a, g, dist, obs["alive"], goal_mask)

    def gm_value(self, obs: dict, scale: float, horizon: int) -> torch.Tensor:
        a, g, _ = gm_inputs(obs, scale, self.max_speed)
        return self.gm_critic(a, g, obs["alive"], global_features(obs, horizon))

    def gm_forward(self, obs: dict, scale: float, horizon: int) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`gm_logits` and :meth:`gm_value` from one :func:`gm_inputs` (what training calls)."""
        a, g, dist = gm_inputs(obs, scale, self.max_speed)
        return self.gm(a, g, dist, obs["alive"]), self.gm_critic(a, g, obs["alive"], global_features(obs, horizon))


class MASPNets(GoalMatcherCalls, nn.Module):
    """Both levels' actors and critics, built from a :class:`~masp_lite.config.NetConfig`.

    ``MASPNets(NetConfig(width=32, ...))`` or ``MASPNets(width=32, ...)``; ``arch`` is the
    configuration as a dict, the form weights files store (:mod:`masp_lite.weights`).
    """

    def __init__(self, config: NetConfig | None = None, **arch):
        super().__init__()
        if config is not None and arch:
            raise ValueError("MASPNets: expected a NetConfig or keyword settings, not both")
        try:
            self.config = config if config is not None else NetConfig(**arch)
        except TypeError as e:
            raise ValueError(f"MASPNets: {e}; expected settings among {sorted(NetConfig.__dataclass_fields__)}") \
                from None
        c = self.config
        if c.fixed_size and c.team_size < 2:
            raise ValueError("MASPNets: an mlp variant needs team_size (the agents it is built for), got "
                             f"{c.team_size}")
        # "random" and "hungarian" keep a (never trained, never used) Goal Matcher: every weights file has one layout
        variant = c.goal_matcher in ("mlp", "none") or c.executor != "graph"
        if variant:  # an ablation's or baseline's parts, beside MASP's (built in this order: the same initial weights)
            from . import variants
            from .baselines import landmark_features
            self.landmark_features = landmark_features  # the goal-free baselines' view of every landmark
        self.gm = variants.goal_matcher(c) if c.goal_matcher == "mlp" else GoalMatcher(c.width)
        self.gm_critic = GoalMatcherCritic(c.width)
        fusion, landmarks = variants.executor_parts(c, PAIR_FEATURES, LANDMARK_FEATURES) if variant else (None, None)
        self.cae = CoordinatedActionExecutor(c.width, c.gcn_layers, c.obstacles_seen, fusion, landmarks)
        self.cae_critic = ExecutorCritic(c.width)

    @property
    def arch(self) -> dict:
        """The architecture as a plain dict (``NetConfig``'s fields)."""
        return dataclasses.asdict(self.config)

    def cae_inputs(self, obs: dict, goals: torch.Tensor | None, perm: torch.Tensor) -> tuple:
        """Executor inputs for goal indices ``goals`` (B, N) and random group order ``perm`` (B, N).

        ``goals`` None (the goal-free baselines): every landmark instead
        (:func:`masp_lite.nets.baselines.landmark_features`)."""
        pos, vel = obs["agent_pos"], obs["agent_vel"]
        if goals is None:
            goal_f = self.landmark_features(pos, vel, obs["landmark_pos"], obs["covered"], MAX_SPEED)
        else:
            goal_f = goal_features(pos, vel, torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(pos)))
        return (pair_features(pos, vel), group_division(perm, self.config.group_size), obs["alive"], goal_f,
                obstacle_features(pos, obs["obstacle_pos"], self.config.obstacles_seen))

    def cae_logits(self, inputs: tuple) -> torch.Tensor:
        return self.cae(*inputs)

    def cae_forward(self, inputs: tuple, obs: dict, horizon: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Executor logits (B, N, 5) and critic values (B, N) from one pass of the fusion."""
        feats = self.cae.features(*inputs)
        return self.cae.head(torch.cat(feats, dim=-1)), self.cae_critic(feats, critic_extra(self.config, obs, horizon))
