"""MASP's two policies and their centralized critics, and what they observe.

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
so the networks run for any team size. Executor inputs are in metres (MPE's dynamics do
not scale with the map); relative vectors are clipped at ``SENSE`` = 1 m for neighbours
and obstacles (collisions happen below 0.2 m).
"""
from __future__ import annotations

import torch
from torch import nn

from ..envs.particle import NUM_ACTIONS
from .encoders import CrossEncoder, SelfEncoder, mlp
from .fusion import GroupInformationFusion

__all__ = ["GoalMatcher", "GoalMatcherCritic", "CoordinatedActionExecutor", "ExecutorCritic",
           "pair_features", "neighbour_goal_features", "goal_features", "obstacle_features", "global_features",
           "gm_inputs",
           "MASPNets", "MASPPolicy", "MAX_SPEED", "SENSE"]

MAX_SPEED = 2.0
"""MPE's terminal speed under a constant action (m/s); velocities are divided by it."""
SENSE = 1.0
"""Metres at which neighbour and obstacle vectors are clipped."""

PAIR_FEATURES, GOAL_FEATURES, OBSTACLE_FEATURES, GLOBAL_FEATURES = 6, 6, 3, 3
NEIGHBOUR_GOAL_FEATURES = 3


def _clip(rel: torch.Tensor, radius: float) -> tuple[torch.Tensor, torch.Tensor]:
    d = rel.norm(dim=-1, keepdim=True)
    return rel * (radius / d.clamp(min=radius)), d


def pair_features(pos: torch.Tensor, vel: torch.Tensor) -> torch.Tensor:
    """(B, N, N, 6): agent ``j`` seen from agent ``k`` at ``[b, k, j]``.

    ``[rel / SENSE (2, clipped to norm 1), min(dist, SENSE) / SENSE, (v_j - v_k) / MAX_SPEED (2),
    is_self]``.
    """
    rel, d = _clip(pos.unsqueeze(1) - pos.unsqueeze(2), SENSE)
    dv = (vel.unsqueeze(1) - vel.unsqueeze(2)) / MAX_SPEED
    N = pos.shape[1]
    eye = torch.eye(N, dtype=pos.dtype, device=pos.device).expand(*pos.shape[:1], N, N).unsqueeze(-1)
    return torch.cat([rel / SENSE, d.clamp(max=SENSE) / SENSE, dv, eye], dim=-1)


def neighbour_goal_features(pos: torch.Tensor, goal_pos: torch.Tensor) -> torch.Tensor:
    """(B, N, N, 3): agent ``j``'s assigned goal as seen from agent ``k``, at ``[b, k, j]``.

    ``[(g_j - p_k) / SENSE (2, clipped to norm 1), min(|g_j - p_j|, SENSE) / SENSE]``: where
    ``j`` is heading relative to ``k``, and how far ``j`` still has to go (0: ``j`` sits on
    its goal). Appended to :func:`pair_features` when ``MASPNets(neighbour_goals=True)``.
    """
    rel, _ = _clip(goal_pos.unsqueeze(1) - pos.unsqueeze(2), SENSE)
    left = (goal_pos - pos).norm(dim=-1).clamp(max=SENSE) / SENSE
    return torch.cat([rel / SENSE, left.unsqueeze(1).expand(*rel.shape[:3]).unsqueeze(-1)], dim=-1)


def goal_features(pos: torch.Tensor, vel: torch.Tensor, goal_pos: torch.Tensor) -> torch.Tensor:
    """(B, N, 6): each agent's assigned goal ``goal_pos`` (B, N, 2) seen from the agent.

    ``[unit direction (2), min(dist, 1 m), log(1 + dist), own velocity / MAX_SPEED (2)]``.
    """
    rel = goal_pos - pos
    d = rel.norm(dim=-1, keepdim=True)
    unit = rel / d.clamp(min=1e-6)
    return torch.cat([unit, d.clamp(max=1.0), torch.log1p(d), vel / MAX_SPEED], dim=-1)


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


def gm_inputs(obs: dict, scale: float):
    """Goal Matcher inputs: agent nodes (B, N, 5), goal nodes (B, M, 4), pair distances (B, N, M, 2).

    Pair ``(k, j)``: ``[D_kj, D_kj - min_i D_ij]`` — the L2 distance of eq. 4 and how much
    farther agent ``k`` is from goal ``j`` than the closest alive agent (0 when ``k`` is
    the closest).

    Agent node: ``[pos / scale (2), vel / MAX_SPEED (2), distance to its nearest goal / scale]``;
    goal node: ``[pos / scale (2), covered, distance to its nearest alive agent / scale]``
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
    a = torch.cat([obs["agent_pos"] / scale, obs["agent_vel"] / MAX_SPEED, near_goal], dim=-1)
    g = torch.cat([obs["landmark_pos"] / scale, obs["covered"].to(a.dtype).unsqueeze(-1), near_agent], dim=-1)
    margin = (dist - near_agent.transpose(1, 2)).clamp(min=0.0, max=4.0)
    return a, g, torch.stack([dist, margin], dim=-1)


class _GraphEncoders(nn.Module):
    def __init__(self, width: int):
        super().__init__()
        self.embed_agent = mlp([5, width], last_activation=True)
        self.embed_goal = mlp([4, width], last_activation=True)
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

    def __init__(self, width: int = 32):
        super().__init__(width)
        self.cross = CrossEncoder(width, distance_channels=2)

    def forward(self, agent_x, goal_x, dist, alive, goal_mask=None):
        ya, yt = self.encode(agent_x, goal_x, alive)
        return self.cross(ya, yt, dist, goal_mask)


class GoalMatcherCritic(_GraphEncoders):
    """Centralized high-level critic: ``forward(agent_x, goal_x, alive, extra) -> (B, N)``.

    Agent ``k``'s value reads its own encoded node, the mean of the alive agents' nodes,
    the mean of the goal nodes and :func:`global_features`.
    """

    def __init__(self, width: int = 32):
        super().__init__(width)
        self.head = mlp([3 * width + GLOBAL_FEATURES, width, 1])

    def forward(self, agent_x, goal_x, alive, extra):
        ya, yt = self.encode(agent_x, goal_x, alive)
        w = alive.to(ya.dtype).unsqueeze(-1)
        pooled = (ya * w).sum(1, keepdim=True) / w.sum(1, keepdim=True).clamp(min=1)
        x = torch.cat([ya, pooled.expand_as(ya), yt.mean(1, keepdim=True).expand_as(ya), extra], dim=-1)
        return self.head(x).squeeze(-1)


class CoordinatedActionExecutor(nn.Module):
    """Low-level actor: ``forward(pair, groups, alive, goal_f, obstacle_f) -> logits`` (B, N, 5)."""

    def __init__(self, width: int = 32, gcn_layers: int = 1, obstacles_seen: int = 2, neighbour_goals: bool = False):
        super().__init__()
        pair = PAIR_FEATURES + (NEIGHBOUR_GOAL_FEATURES if neighbour_goals else 0)
        self.fusion = GroupInformationFusion(pair, width, gcn_layers)
        self.goal_embed = mlp([GOAL_FEATURES, width], last_activation=True)
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


class MASPNets(nn.Module):
    """Both levels' actors and critics, with the architecture in ``arch`` (saved in checkpoints).

    ``arch``: ``width`` (L = 32), ``group_size`` (N_g = 3), ``gcn_layers``, ``obstacles_seen``,
    ``global_step`` (environment steps per Goal Matcher decision, 3 in the paper),
    ``group_order``: how agent ``k``'s others are ordered before they are cut into groups,
    ``"random"`` (the paper's random division) or ``"nearest"`` (by distance from ``k``,
    :func:`~masp_lite.nets.fusion.nearest_order`). Files saved before ``group_order``
    existed load as ``"random"``, and ``arch`` lists ``group_order`` only when it is not
    ``"random"``, so their records stay equal.
    ``neighbour_goals``: the executor's node of agent ``j`` (seen from ``k``) also holds
    ``j``'s assigned goal (:func:`neighbour_goal_features`). The paper says the nodes hold the
    agents' state but does not list it; in a goal-conditioned task an agent's goal is part
    of its state, and knowing whether a neighbour is settled on a
    goal beside one's own is what avoiding a late push needs. Off (``False``, not listed in
    ``arch``) for every file saved before the option existed. :meth:`with_neighbour_goals`
    turns a network without it into one with it that acts identically (zero weights on the
    new inputs), a starting point for fine-tuning.
    """

    def __init__(self, width: int = 32, group_size: int = 3, gcn_layers: int = 1,
                 obstacles_seen: int = 2, global_step: int = 3, group_order: str = "random",
                 neighbour_goals: bool = False):
        super().__init__()
        for name, v, low in (("width", width, 1), ("group_size", group_size, 2), ("gcn_layers", gcn_layers, 1),
                             ("obstacles_seen", obstacles_seen, 1), ("global_step", global_step, 1)):
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"{name}: expected an int >= {low}, got {v!r}")
        if group_order not in ("random", "nearest"):
            raise ValueError(f"group_order: expected 'random' or 'nearest', got {group_order!r}")
        self.arch = dict(width=width, group_size=group_size, gcn_layers=gcn_layers,
                         obstacles_seen=obstacles_seen, global_step=global_step)
        if not isinstance(neighbour_goals, bool):
            raise ValueError(f"neighbour_goals: expected True or False, got {neighbour_goals!r}")
        if group_order != "random":
            self.arch["group_order"] = group_order
        if neighbour_goals:
            self.arch["neighbour_goals"] = True
        self.gm = GoalMatcher(width)
        self.gm_critic = GoalMatcherCritic(width)
        self.cae = CoordinatedActionExecutor(width, gcn_layers, obstacles_seen, neighbour_goals)
        self.cae_critic = ExecutorCritic(width)

    def with_neighbour_goals(self) -> "MASPNets":
        """A copy with ``neighbour_goals`` on that acts exactly like ``self``: the fusion's
        input layer gets zero weights for the new inputs, every other weight is copied."""
        if self.arch.get("neighbour_goals", False):
            raise ValueError("with_neighbour_goals: these networks already see the neighbours' goals")
        new = MASPNets(**self.arch, neighbour_goals=True)
        state = self.state_dict()
        key = "cae.fusion.embed.0.weight"
        w = state[key]
        state[key] = torch.cat([w, w.new_zeros(w.shape[0], NEIGHBOUR_GOAL_FEATURES)], dim=1)
        new.load_state_dict(state)
        return new

    def gm_logits(self, obs: dict, scale: float, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
        a, g, dist = gm_inputs(obs, scale)
        return self.gm(a, g, dist, obs["alive"], goal_mask)

    def gm_value(self, obs: dict, scale: float, horizon: int) -> torch.Tensor:
        a, g, _ = gm_inputs(obs, scale)
        return self.gm_critic(a, g, obs["alive"], global_features(obs, horizon))

    def cae_inputs(self, obs: dict, goals: torch.Tensor, perm: torch.Tensor) -> tuple:
        """Executor inputs for goal indices ``goals`` (B, N) and group order ``perm`` (B, N).

        With ``arch["group_order"] == "nearest"`` the order comes from the positions and
        ``perm`` is not used."""
        from .fusion import group_division, nearest_order
        pos, vel = obs["agent_pos"], obs["agent_vel"]
        if self.arch.get("group_order", "random") == "nearest":
            perm = nearest_order(pos, obs["alive"])
        goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(pos))
        pair = pair_features(pos, vel)
        if self.arch.get("neighbour_goals", False):
            pair = torch.cat([pair, neighbour_goal_features(pos, goal_pos)], dim=-1)
        return (pair, group_division(perm, self.arch["group_size"]), obs["alive"],
                goal_features(pos, vel, goal_pos),
                obstacle_features(pos, obs["obstacle_pos"], self.arch["obstacles_seen"]))

    def cae_logits(self, inputs: tuple) -> torch.Tensor:
        return self.cae(*inputs)

    def cae_forward(self, inputs: tuple, obs: dict, horizon: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Executor logits (B, N, 5) and critic values (B, N) from one pass of the fusion."""
        feats = self.cae.features(*inputs)
        return self.cae.head(torch.cat(feats, dim=-1)), self.cae_critic(feats, global_features(obs, horizon))


class MASPPolicy:
    """``masp`` for :mod:`masp_lite.eval`: trained Goal Matcher + executor on a particle world.

    ``checkpoint``: a weights file (default: the shipped one for the world's scenario, see
    :mod:`masp_lite.checkpoints`). ``seed`` seeds the random group division. ``global_step``
    overrides the checkpoint's Goal Matcher period. ``deterministic``: take the most likely
    goals and action (the paper's "highest matching score"); ``False`` samples both.
    ``decode``: how the Goal Matcher's scores become goals (:mod:`masp_lite.nets.decoding`):
    ``"joint"`` (default) gives the alive agents distinct goals — the most likely such
    assignment, or the sequential draw of training when sampling; ``"independent"`` lets
    every agent take its own best goal, duplicates allowed (the paper's literal wording);
    ``"hungarian"`` bypasses the Goal Matcher and takes the Hungarian assignment
    (:func:`masp_lite.algos.assignment.hungarian`, the goals of ``h-greedy`` and of R_GM's
    reference) every global step (an agent it leaves without a goal, when a shrinking team
    has more agents than unreached landmarks, heads for its nearest landmark). That is not MASP: it is a diagnostic that tells the two
    levels apart (the executor's share of a gap to ``h-greedy`` versus the Goal Matcher's).
    With a team change (``mpe-20to10``, ...) the success rate counts landmarks ever
    reached, so the Goal Matcher's choice is restricted to landmarks not reached yet (all
    of them once every one has been reached); fixed teams choose among all landmarks.
    """

    def __init__(self, world, checkpoint: str | None = None, seed: int = 0, global_step: int | None = None,
                 deterministic: bool = True, any_scenario: bool = False, decode: str = "joint"):
        from ..checkpoints import load_weights
        if getattr(world.scenario, "kind", None) != "particle":
            raise ValueError("masp: expected a particle world (mpe-* scenario)")
        self.world = world
        self.nets, self.meta = load_weights(checkpoint, scenario=world.scenario, any_scenario=any_scenario)
        self.nets.eval()
        gs = self.nets.arch["global_step"] if global_step is None else global_step
        if isinstance(gs, bool) or not isinstance(gs, int) or gs < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        self._setup(gs, deterministic, seed, decode)

    def _setup(self, global_step, deterministic, seed, decode):
        from .decoding import DECODERS
        if decode not in (*DECODERS, "hungarian"):
            raise ValueError(f"decode: expected one of {[*DECODERS, 'hungarian']}, got {decode!r}")
        self.global_step, self.deterministic, self.seed = global_step, bool(deterministic), int(seed)
        self.decode = decode
        self.scale = self.world.scenario.world_size / 2
        self.generator = torch.Generator().manual_seed(self.seed)
        self.goals = None

    @classmethod
    def from_nets(cls, world, nets: MASPNets, seed: int = 0, deterministic: bool = True,
                  decode: str = "joint") -> "MASPPolicy":
        """A policy around networks in memory (used by training's periodic evaluation)."""
        self = cls.__new__(cls)
        self.world, self.nets, self.meta = world, nets, {}
        self._setup(nets.arch["global_step"], deterministic, seed, decode)
        return self

    def reset(self, obs) -> None:
        self.goals = None

    def _pick(self, logits):
        if self.deterministic:
            return logits.argmax(-1)
        u = torch.rand(logits.shape, generator=self.generator).to(logits.device)
        return (logits - torch.log(-torch.log(u.clamp(1e-10, 1.0)))).argmax(-1)

    def _goals(self, logits, alive, mask):
        from .decoding import joint_argmax, sequential_sample
        if self.decode == "independent":
            return self._pick(logits)
        if self.deterministic:
            return joint_argmax(logits, alive, mask)
        return sequential_sample(logits.cpu(), alive.cpu(), self.generator, None if mask is None else mask.cpu())[0] \
            .to(logits.device)

    @torch.inference_mode()
    def act(self, obs) -> torch.Tensor:
        due = obs["t"] % self.global_step == 0
        if self.goals is None or bool(due.any()):
            mask = None
            if self.world.scenario.varying:  # landmarks already reached count for SR; pick among the rest
                mask = ~obs["reached"] | obs["reached"].all(-1, keepdim=True)
            if self.decode == "hungarian":  # diagnostic: the Hungarian reference instead of the Goal Matcher
                from ..algos.assignment import hungarian
                new = hungarian(obs["agent_pos"], obs["landmark_pos"], obs["alive"], mask)
                nearest = torch.cdist(obs["agent_pos"], obs["landmark_pos"]).argmin(-1)
                new = torch.where(new >= 0, new, nearest)  # agents left without a goal: the nearest landmark
            else:
                new = self._goals(self.nets.gm_logits(obs, self.scale, mask), obs["alive"], mask)
            self.goals = new if self.goals is None else torch.where(due.unsqueeze(-1), new, self.goals)
        B, N = self.goals.shape
        perm = torch.rand(B, N, generator=self.generator).argsort(-1).to(self.goals.device)
        actions = self._pick(self.nets.cae_logits(self.nets.cae_inputs(obs, self.goals, perm)))
        return torch.where(obs["alive"], actions, torch.zeros_like(actions))
