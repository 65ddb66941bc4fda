"""MASP's networks for the quadrotor world: the same two levels in 3-D, with a Gaussian executor.

:class:`DroneNets` is :class:`~masp_lite.nets.masp.MASPNets` (the same constructor, variants,
Goal Matcher calls, executor inputs and critics, node for node) with only what differs:

* **3-D**: the Goal Matcher's nodes (:func:`~masp_lite.nets.features.gm_inputs`: positions over
  the map's half-width, velocities over ``DRONE_SPEED``), trained on R_GM (eq. 1) against the 3-D
  Hungarian assignment; the pair features (:func:`~masp_lite.nets.features.pair_features`) clipped
  at ``DRONE_SENSE`` = 2 m (two drones touch below 0.54 m and fly at up to 4 m/s) and the assigned
  goal's features in 3-D;
* **the executor's own input** (:class:`DroneExecutorInputs`): in place of obstacles (the drone
  world has none), the drone's flight state (:func:`drone_state_features`: its attitude, body
  rates, height and rotor throttles — what a motor-level controller needs);
* **the executor** (:class:`DroneExecutor`): its actions (``NetConfig.action``) are a Gaussian
  with a learned, state-independent log-std per dimension (initialised at
  ``NetConfig.log_std_init``), as MAPPO's continuous policies:

  - ``throttle`` (the paper's): 4 motor commands; the mean is ``HOVER_COMMAND`` plus the
    head's output, whose last layer starts near 0, so an untrained executor hovers;
  - ``velocity`` (the variant ``masp-velocity``): a 3-D velocity set-point in units of
    ``DRONE_SPEED``, flown by the geometric controller
    (:func:`masp_lite.planners.geometric.motor_commands`).

  A sample is clipped to [−1, 1] before it reaches the world or the controller; the policy
  is trained on the log-probability of the unclipped sample (the clip belongs to the world),
  which keeps the log-probability exact and the entropy in closed form
  (:func:`gaussian_log_prob`). The deterministic action is the clipped mean.

Every weight acts per node, pair or group, so the networks fly any team size (drone-5
weights fine-tune on drone-20, drone-20 weights fly drone-20to10).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import nn

from ..config import NetConfig
from ..envs.drone_model import DRONE_SPEED, HOVER_COMMAND, quat_to_matrix
from ..envs.drones import FLIGHT_HEIGHT
from .encoders import mlp
from .fusion import GroupInformationFusion
from .masp import MASPNets

__all__ = ["DroneNets", "DroneExecutor", "DroneExecutorInputs", "drone_state_features", "gaussian_log_prob",
           "gaussian_entropy", "DRONE_SPEED", "DRONE_SENSE", "ACTION_SIZE"]

DRONE_SENSE = 2.0
"""Metres at which neighbour vectors are clipped."""
ANGVEL_SCALE = 10.0
"""rad/s: body rates are divided by it."""
PAIR_FEATURES, GOAL_FEATURES, STATE_FEATURES, LANDMARK_FEATURES = 8, 8, 17, 9
#: Action dimensions per drone for each ``NetConfig.action``.
ACTION_SIZE = {"throttle": 4, "velocity": 3}


class DroneExecutorInputs(NamedTuple):
    """A drone executor's inputs for one step (a tuple too: ``executor(*inputs)``): those of the particle
    world's :class:`~masp_lite.nets.features.ExecutorInputs` in 3-D, with the flight state for obstacles."""

    pair: torch.Tensor     # (B, N, N, 8) pair_features, clipped at DRONE_SENSE
    groups: torch.Tensor   # (B, N, G, n) group_division (long)
    alive: torch.Tensor    # (B, N)
    goal: torch.Tensor     # (B, N, 8) goal_features; (B, N, M, 9) landmark_features without goals
    flight: torch.Tensor   # (B, N, 17) drone_state_features


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
    """Low-level actor: ``forward(*inputs) -> (mean, log_std)``, (B, N, A) and (A,), ``inputs`` a
    :class:`DroneExecutorInputs`."""

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

    def features(self, pair, groups, alive, goal, flight) -> list:
        """The three features the head (and the critic) read: fusion, goal, flight state, each (B, N, width)."""
        return [self.fusion(pair, groups, alive), self.goal_embed(goal), self.state_embed(flight)]

    def output(self, features: list):
        """``(mean, log_std)`` of the Gaussian from :meth:`features`."""
        return self.head(torch.cat(features, dim=-1)) + self.offset, self.log_std

    def forward(self, pair, groups, alive, goal, flight):
        return self.output(self.features(pair, groups, alive, goal, flight))


class DroneNets(MASPNets):
    """Both levels' actors and critics for drones, from a :class:`~masp_lite.config.NetConfig` whose ``action``
    is ``throttle`` or ``velocity``: :class:`~masp_lite.nets.masp.MASPNets` with the drone world's part."""

    world, dims = "drone", 3
    sense = DRONE_SENSE  # metres at which the pair features clip (a research subclass may see farther)
    max_speed = DRONE_SPEED  # what velocities are divided by
    pair_size, landmark_size = PAIR_FEATURES, LANDMARK_FEATURES
    inputs_type = DroneExecutorInputs

    def build_executor(self, c: NetConfig, fusion: nn.Module | None, goal_embed: nn.Module | None) -> nn.Module:
        return DroneExecutor(c.width, c.gcn_layers, c.action, c.log_std_init, fusion, goal_embed)

    def own_features(self, obs: dict) -> torch.Tensor:
        """The executor's input beside the team and the goal: the drone's flight state."""
        return drone_state_features(obs)
