"""Reference methods: a random policy and ``h-greedy`` (Hungarian + straight line).

Neither is in the paper's tables; they bracket them. ``random`` is the floor every learned
method must beat. ``h-greedy`` is the simplest member of the paper's "(H)" family
(section "Baselines": "we utilize the Hungarian algorithm represented as '(H)' for goal
assignment"): the same Hungarian goal assignment every global step (3 environment steps,
as MASP's Goal Matcher), followed by a straight line to the goal with no collision
avoidance at all. The planners ((H)ORCA, (H)RRT*, (H)Voronoi) replace only the straight
line, so the difference to ``h-greedy`` is what their path planning buys.

The low-level controller is MPE's own dynamics run backwards, hand-written because no
library knows MPE's discrete actions: from velocity ``v`` an action ``a`` leads to
``v' = (1 - damping) v + e(a) s dt / m`` (``e(a)`` the action's unit direction, ``s`` the
sensitivity; contact forces ignored), so ``velocity_to_action`` (shared with the planners,
:mod:`masp_lite.planners.controllers`, and re-exported here) predicts ``v'`` for the five
actions and keeps the one closest to the desired velocity. The desired velocity points at
the goal with a speed that lets the agent brake to a stop on it (:func:`braking_speed`).
"""
from __future__ import annotations

import math

import torch

from ..algos.assignment import check_power
from ..algos.team import TEAM_PROTOCOLS, TeamAssignment
from ..envs.particle import ACTION_DIRECTIONS, PHYSICS
from ..planners.controllers import velocity_to_action  # the controller every planner shares

__all__ = ["RandomPolicy", "HungarianGreedy", "TeamAssignment", "TEAM_PROTOCOLS", "capt", "min_max", "COSTS",
           "velocity_to_action", "braking_speed",
           "MAX_SPEED"]

COSTS = ("sum", "bottleneck")
"""What h-greedy's assignment minimises: the total of ``distance ** power``, or the longest trip."""

#: Terminal speed under a constant action: ``v = (1 - damping) v + s dt / m`` -> 2 m/s in MPE.
MAX_SPEED = PHYSICS["sensitivity"] * PHYSICS["dt"] / PHYSICS["mass"] / PHYSICS["damping"]


def braking_speed(distance: torch.Tensor) -> torch.Tensor:
    """Largest speed from which full braking stops the agent within ``distance`` (m).

    Braking applies the action opposite to the motion every step, so the speed follows
    ``v_{k+1} = (1 - damping) v_k - s dt / m`` and the agent travels ``dt * v_k`` per step.
    With ``c = 1 - damping`` and ``u = s dt / (m damping)`` (= 2 m/s, the terminal speed),
    ``v_k = (v + u) c^k - u``. This function inverts, for the stop distance, the continuous
    version of that sum: ``D(v) = dt * [(v + u)(1 - c^K) / (1 - c) - u K]`` with ``K`` the
    (real) number of steps until ``v_K = 0``, ``c^K = u / (v + u)`` — so
    ``D(v) = dt * [v / (1 - c) - u ln(1 + v / u) / ln(1 / c)]``. It is inverted by a few
    Newton steps (``D`` is convex and increasing), then capped at :data:`MAX_SPEED`.
    """
    p = PHYSICS
    c, u, dt = 1 - p["damping"], MAX_SPEED, p["dt"]
    lc = math.log(1 / c)
    d = distance.clamp(min=0.0)
    v = (d / dt * (1 - c)).clamp(max=MAX_SPEED)  # start from the damping-only guess
    v = torch.maximum(v, d.new_tensor(1e-6))
    for _ in range(8):
        f = dt * (v / (1 - c) - u * torch.log1p(v / u) / lc) - d
        df = dt * (1 / (1 - c) - 1 / ((1 + v / u) * lc))
        v = (v - f / df).clamp(min=0.0)
    return v.clamp(max=MAX_SPEED)


class RandomPolicy:
    """Uniformly random actions: ids in [0, 5) for particles, motor commands in [-1, 1] for drones.

    ``seed`` seeds the policy's own generator (the world's randomness is separate), so the
    same seed gives the same actions.
    """

    def __init__(self, world, seed: int = 0):
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"seed: expected an int, got {seed!r}")
        self.world = world
        self.seed = seed
        self.generator = torch.Generator().manual_seed(seed)

    def reset(self, obs) -> None:
        pass

    def act(self, obs) -> torch.Tensor:
        B, N = self.world.num_envs, self.world.num_agents
        if self.world.scenario.kind == "drone":
            cmd = torch.rand(B, N, 4, generator=self.generator) * 2 - 1
            return cmd.to(obs["agent_pos"].device)
        return torch.randint(0, len(ACTION_DIRECTIONS), (B, N), generator=self.generator).to(
            obs["agent_pos"].device)


class HungarianGreedy:
    """``h-greedy``: Hungarian goal assignment every ``global_step`` steps, then straight lines.

    Assignment (every ``global_step`` environment steps, starting at t = 0): fixed teams —
    :func:`~masp_lite.algos.assignment.hungarian` of the alive agents over all landmarks
    (a square problem); varying teams — over the landmarks not yet reached, since the
    success rate there counts landmarks ever reached (rectangular: with more unreached
    landmarks than agents the least-cost subset is chosen; with fewer, the extra agents
    get no goal). ``power`` is the assignment's cost, ``distance ** power`` (1: total
    distance, the "(H)" baselines' and the default; 2: total squared distance, shorter
    longest trips, see :func:`~masp_lite.algos.assignment.hungarian`). ``cost="bottleneck"``
    takes the min–max assignment instead (:func:`~masp_lite.algos.team.bottleneck`:
    the longest trip as short as possible, then the least total). ``team_protocol``: how a
    shrunk team is assigned (:data:`TEAM_PROTOCOLS`; default ``resolve``). A world whose team
    has just shrunk is reassigned at once rather than at its next global step, so the
    survivors take over the dropped agents' landmarks without delay. The current assignment
    is kept in ``self.assignment`` (B, N), ``-1`` for none, for playback.

    Motion (every step, vectorized over worlds and agents): let ``d`` be the distance to
    the goal from ``pos + vel * dt``, where the current velocity alone would take the agent
    in one step (exactly where it goes in mpe2's order; in the paper's velocity-first order,
    which also damps and pushes first, a look-ahead the same for every method built on
    this controller), and ``r = r_agent + r_landmark`` the reach distance. The desired
    velocity points at the goal with speed :func:`braking_speed` of ``d - r / 3`` (aim to
    stop a little short, since the discrete actions change the speed by 0.5 m/s per step
    and overshoot), and is zero once ``d < r / 2`` (the agent covers the landmark: brake
    and hold, rather than dither around its centre and bump neighbours). These two
    margins were chosen on seeded ``mpe-5``/``mpe-20`` runs, where they lower CR without
    costing SR. :func:`velocity_to_action` turns the desired velocity into an action.
    Agents without a goal brake to a stop. No collision avoidance.

    On drone worlds the method table gives ``h-greedy`` to
    :class:`masp_lite.policies.drones.DroneHungarianGreedy` (its own options).
    """

    def __init__(self, world, global_step: int = 3, power: float = 1.0, cost: str = "sum",
                 team_protocol: str = "resolve", **options):
        if options:
            raise ValueError(f"h-greedy: unknown option(s) {sorted(options)}; expected global_step, power, cost, "
                             "team_protocol")
        if isinstance(global_step, bool) or not isinstance(global_step, int) or global_step < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        if cost not in COSTS:
            raise ValueError(f"cost: expected one of {list(COSTS)}, got {cost!r}")
        self.world = world
        self.global_step = global_step
        self.power = check_power(power)
        self.cost = cost
        self.varying = bool(world.scenario.varying)
        self.team = TeamAssignment(team_protocol, self.varying, cost, self.power)
        self.assignment = None
        self._alive = None

    def reset(self, obs) -> None:
        self.assignment = None
        self._alive = None
        self.team.reset()

    def assign(self, obs) -> torch.Tensor:
        """The assignment for the current observation (see the class docstring)."""
        return self.team.assign(obs, self.assignment)

    def act(self, obs) -> torch.Tensor:
        t = obs["t"]
        due = (t % self.global_step == 0)
        if self._alive is not None:  # the team just changed: reassign now, not at the next global step
            due = due | (obs["alive"] != self._alive).any(dim=1)
        self._alive = obs["alive"].clone()
        if self.assignment is None:
            self.assignment = self.assign(obs)
        elif bool(due.any()):
            self.assignment = torch.where(due.unsqueeze(-1), self.assign(obs), self.assignment)
        pos, vel = obs["agent_pos"], obs["agent_vel"]
        has_goal = (self.assignment >= 0) & obs["alive"]
        idx = self.assignment.clamp(min=0).unsqueeze(-1).expand_as(pos)
        goal = torch.gather(obs["landmark_pos"], 1, idx)
        drift = pos + vel * PHYSICS["dt"]                       # where the current velocity alone leads
        to_goal = goal - drift
        dist = to_goal.norm(dim=-1, keepdim=True)
        reach = self.world.scenario.reach_distance
        speed = braking_speed((dist - reach / 3).clamp(min=0.0))  # aim to stop just short of it
        speed = torch.where(dist < reach / 2, torch.zeros_like(speed), speed)  # close enough: stop
        desired = to_goal / dist.clamp(min=1e-9) * speed
        desired = torch.where(has_goal.unsqueeze(-1), desired, torch.zeros_like(desired))
        return velocity_to_action(vel, desired)


def capt(world, global_step: int = 3) -> HungarianGreedy:
    """``h-capt``: h-greedy with the Hungarian assignment on squared distances.

    Turpin et al.'s goal assignment for interchangeable robots (CAPT, cited by the paper),
    which minimises the sum of squared trips and so shortens the longest one. Particle worlds only."""
    if getattr(getattr(world, "scenario", None), "kind", None) == "drone":
        raise ValueError("h-capt: expected a particle world (mpe-*); on drones use h-greedy or h-bottleneck")
    return HungarianGreedy(world, global_step=global_step, power=2.0)


def min_max(world, global_step: int = 3) -> HungarianGreedy:
    """``h-bottleneck``: h-greedy with the min–max assignment, re-solved every global step.

    Not in the paper: Steps waits for the last landmark, so the assignment whose longest
    trip is shortest (:func:`~masp_lite.algos.team.bottleneck`) bounds what any
    goal assignment followed by straight lines can do. On drone worlds the method table gives
    ``h-bottleneck`` to :class:`masp_lite.policies.drone_planners.DroneBottleneck` (the same
    assignment, straight flights)."""
    return HungarianGreedy(world, global_step=global_step, cost="bottleneck")
