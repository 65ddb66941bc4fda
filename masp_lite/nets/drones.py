"""MASP's networks for the quadrotor world: the same two levels in 3-D, with a Gaussian executor.

The design is the particle world's (:mod:`masp_lite.nets.masp`), node for node:

* **Goal Matcher**: :class:`~masp_lite.nets.masp.GoalMatcher` on 3-D nodes
  (:func:`~masp_lite.nets.masp.gm_inputs`: positions over the map's half-width, velocities
  over ``DRONE_SPEED``), trained on R_GM (eq. 1) against the 3-D Hungarian assignment.
* **Executor** (:class:`DroneExecutor`): the Group Information Fusion over 3-D pair features
  (:func:`~masp_lite.nets.masp.pair_features`, clipped at ``DRONE_SENSE`` = 2 m: two drones
  touch below 0.54 m and fly at up to 4 m/s), the assigned goal's embedding
  (:func:`~masp_lite.nets.masp.goal_features` in 3-D) and, in place of obstacles (the
  drone world has none), the drone's own flight state (:func:`drone_state_features`: its
  attitude, body rates, height and rotor throttles — what a motor-level controller needs).
* **Actions** (``NetConfig.action``), a Gaussian with a learned, state-independent log-std
  per dimension (initialised at ``NetConfig.log_std_init``), as MAPPO's continuous policies:

  - ``throttle`` (the paper's): 4 motor commands; the mean is ``HOVER_COMMAND`` plus the
    head's output, whose last layer starts near 0, so an untrained executor hovers;
  - ``velocity`` (the variant ``masp-velocity``): a 3-D velocity set-point in units of
    ``DRONE_SPEED``, flown by the geometric controller
    (:func:`masp_lite.planners.geometric.motor_commands`).

  A sample is clipped to [−1, 1] before it reaches the world or the controller; the policy
  is trained on the log-probability of the unclipped sample (the clip belongs to the world),
  which keeps the log-probability exact and the entropy in closed form
  (:func:`gaussian_log_prob`). The deterministic action is the clipped mean.
* **Critics**: :class:`~masp_lite.nets.masp.GoalMatcherCritic` on the 3-D nodes and
  :class:`~masp_lite.nets.masp.ExecutorCritic` on the executor's features, as in MPE.

Every weight acts per node, pair or group, so the networks fly any team size (drone-5
weights fine-tune on drone-20, drone-20 weights fly drone-20to10).
"""
from __future__ import annotations

import dataclasses
import math

import torch
from torch import nn

from ..config import NetConfig
from ..envs.drone_model import DRONE_SPEED, HOVER_COMMAND, quat_to_matrix
from ..envs.drones import FLIGHT_HEIGHT
from .baselines import landmark_features
from .encoders import mlp
from .fusion import GroupInformationFusion, group_division
from .masp import (
    ExecutorCritic,
    GoalMatcher,
    GoalMatcherCalls,
    GoalMatcherCritic,
    critic_extra,
    goal_features,
    pair_features,
)

__all__ = ["DroneNets", "DroneExecutor", "drone_state_features", "gaussian_log_prob", "gaussian_entropy",
           "DRONE_SPEED", "DRONE_SENSE", "ACTION_SIZE"]

DRONE_SENSE = 2.0
"""Metres at which neighbour vectors are clipped."""
ANGVEL_SCALE = 10.0
"""rad/s: body rates are divided by it."""
PAIR_FEATURES, GOAL_FEATURES, STATE_FEATURES, LANDMARK_FEATURES = 8, 8, 17, 9
#: Action dimensions per drone for each ``NetConfig.action``.
ACTION_SIZE = {"throttle": 4, "velocity": 3}


def drone_state_features(obs: dict) -> torch.Tensor:
    """(B, N, 17): each drone's own flight state.

    ``[rotation matrix (9, body to world, row-major), body rates / ANGVEL_SCALE (3),
    (height - FLIGHT_HEIGHT) / FLIGHT_HEIGHT, rotor throttles (4)]``.
    """
    q = obs["agent_quat"]
    R = quat_to_matrix(q / q.norm(dim=-1, keepdim=True).clamp(min=1e-9))
    z = (obs["agent_pos"][..., 2:] - FLIGHT_HEIGHT) / FLIGHT_HEIGHT
    return torch.cat([R.flatten(-2), obs["agent_angvel"] / ANGVEL_SCALE, z, obs["throttle"]], dim=-1).to(q.dtype)


def gaussian_log_prob(mean: torch.Tensor, log_std: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
    """Log-density (...) of ``actions`` (..., A) under independent normals N(mean, exp(log_std)²), summed over A."""
    z = (actions - mean) * torch.exp(-log_std)
    return (-0.5 * z * z - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)


def gaussian_entropy(log_std: torch.Tensor, shape) -> torch.Tensor:
    """Entropy (``shape``) of independent normals with per-dimension ``log_std`` (A,), summed over A."""
    return (0.5 + 0.5 * math.log(2 * math.pi) + log_std).sum(-1).expand(shape)


class DroneExecutor(nn.Module):
    """Low-level actor: ``forward(pair, groups, alive, goal_f, state_f) -> (mean, log_std)``, (B, N, A) and (A,)."""

    def __init__(self, width: int = 32, gcn_layers: int = 1, action: str = "throttle", log_std_init: float = -1.6,
                 fusion: nn.Module | None = None, goal_embed: nn.Module | None = None):
        super().__init__()
        if action not in ACTION_SIZE:
            raise ValueError(f"action: expected one of {list(ACTION_SIZE)} for drones, got {action!r}")
        A = ACTION_SIZE[action]
        self.fusion = GroupInformationFusion(PAIR_FEATURES, width, gcn_layers) if fusion is None else fusion
        self.goal_embed = mlp([GOAL_FEATURES, width], last_activation=True) if goal_embed is None else goal_embed
        self.state_embed = mlp([STATE_FEATURES, width], last_activation=True)
        self.head = mlp([3 * width, width, width, A])
        last = self.head[-1]
        with torch.no_grad():  # the untrained executor asks for the offset: hover, or stand still
            last.weight.mul_(0.01)
            last.bias.zero_()
        self.register_buffer("offset", torch.full((A,), HOVER_COMMAND if action == "throttle" else 0.0))
        self.log_std = nn.Parameter(torch.full((A,), float(log_std_init)))

    def features(self, pair, groups, alive, goal_f, state_f):
        return [self.fusion(pair, groups, alive), self.goal_embed(goal_f), self.state_embed(state_f)]

    def distribution(self, features):
        return self.head(torch.cat(features, dim=-1)) + self.offset, self.log_std

    def forward(self, pair, groups, alive, goal_f, state_f):
        return self.distribution(self.features(pair, groups, alive, goal_f, state_f))


class DroneNets(GoalMatcherCalls, nn.Module):
    """Both levels' actors and critics for drones, from a :class:`~masp_lite.config.NetConfig`
    whose ``action`` is ``throttle`` or ``velocity``; the interface of :class:`~masp_lite.nets.masp.MASPNets`."""

    sense = DRONE_SENSE  # metres at which the pair features clip (a research subclass may see farther)
    max_speed = DRONE_SPEED  # what the Goal Matcher's velocities are divided by

    def __init__(self, config: NetConfig | None = None, **arch):
        super().__init__()
        if config is not None and arch:
            raise ValueError("DroneNets: expected a NetConfig or keyword settings, not both")
        self.config = c = config if config is not None else NetConfig(**arch)
        if c.world != "drone":
            raise ValueError(f"DroneNets: expected a drone action ({list(ACTION_SIZE)}), got {c.action!r}")
        if c.fixed_size and c.team_size < 2:
            raise ValueError(f"DroneNets: an mlp variant needs team_size (the drones it is built for), got "
                             f"{c.team_size}")
        variant = c.goal_matcher in ("mlp", "none") or c.executor != "graph"
        if variant:  # an RL baseline's parts, beside MASP's (built in this order: the same initial weights)
            from . import variants
        self.gm = variants.goal_matcher(c, dims=3) if c.goal_matcher == "mlp" else GoalMatcher(c.width, dims=3)
        self.gm_critic = GoalMatcherCritic(c.width, dims=3)
        fusion, landmarks = variants.executor_parts(c, PAIR_FEATURES, LANDMARK_FEATURES) if variant else (None, None)
        self.cae = DroneExecutor(c.width, c.gcn_layers, c.action, c.log_std_init, fusion, landmarks)
        self.cae_critic = ExecutorCritic(c.width)

    @property
    def arch(self) -> dict:
        return dataclasses.asdict(self.config)

    def cae_inputs(self, obs: dict, goals: torch.Tensor | None, perm: torch.Tensor) -> tuple:
        """Executor inputs ``(pair, groups, alive, goal_f, state_f)`` for goal indices ``goals`` (B, N);
        ``goals`` None (the goal-free baselines): every landmark instead
        (:func:`~masp_lite.nets.baselines.landmark_features`)."""
        pos, vel = obs["agent_pos"], obs["agent_vel"]
        if goals is None:
            goal_f = landmark_features(pos, vel, obs["landmark_pos"], obs["covered"], DRONE_SPEED)
        else:
            goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(pos))
            goal_f = goal_features(pos, vel, goal_pos, DRONE_SPEED)
        return (pair_features(pos, vel, self.sense, DRONE_SPEED), group_division(perm, self.config.group_size),
                obs["alive"], goal_f, drone_state_features(obs))

    def cae_logits(self, inputs: tuple):
        """``(mean, log_std)`` of the executor's Gaussian (the name is the particle networks')."""
        return self.cae(*inputs)

    def cae_forward(self, inputs: tuple, obs: dict, horizon: int):
        """``((mean, log_std), values)`` from one pass of the fusion."""
        feats = self.cae.features(*inputs)
        return self.cae.distribution(feats), self.cae_critic(feats, critic_extra(self.config, obs, horizon))
