"""The (H) planning baselines on drones: (H)ORCA, (H)RRT*, (H)Voronoi and ``h-bottleneck``.

The paper's planning baselines (section "Baselines") in its quadrotor world (section
"Experiments — OmniDrones"), built as the particle-world ones
(:mod:`masp_lite.policies.planners`) are, with the drones'
:class:`~masp_lite.planners.geometric.LeeController` in place of MPE's action picker:

* **Goal assignment, every global step** (3 environment steps): the same
  :class:`~masp_lite.algos.team.TeamAssignment` as the particle planners, on 3-D
  distances — Hungarian over all landmarks for a fixed team, a random subset of the
  unreached landmarks for a varying one (``team_protocol`` as there); ``h-bottleneck``
  takes the min–max assignment instead (:func:`~masp_lite.algos.team.bottleneck`,
  re-solved every global step, as its particle version). A drone left without a goal
  holds the point where it was at that global step. With ``goals="masp"`` (or
  ``"masp-velocity"``; ``checkpoint`` for other weights of that method) the goals are
  instead those MASP's trained Goal Matcher decodes, every one of its global steps
  (:mod:`masp_lite.policies.goal_sources`): MASP's upper level above the planner's flight.
* **Planning in the horizontal plane, at each drone's landmark height.** Every drone heads
  for its goal's altitude at once (the controller's altitude loop) and the planners work
  on ``(x, y)`` with the library's 2-D algorithms, unchanged: ORCA's half-planes and
  linear programs (:mod:`masp_lite.planners.orca`), RRT*'s trees
  (:func:`~masp_lite.planners.rrt_star.plan_rrt_star`), Voronoi routes
  (:func:`~masp_lite.planners.voronoi.plan_voronoi`). Why not 3-D: those algorithms are
  planar (ORCA's programs, the Voronoi roadmap), and the layer the drones fly in is thin —
  landmarks lie at z ∈ [1, 2] m and drones start at 1.5 m, so most pairs come within
  ``2 · COLLISION_RADIUS`` = 0.54 m of each other's height and must pass beside, not over,
  each other; a 3-D planner would find little more room. The third dimension decides who
  is an obstacle to whom: drone ``j`` counts for drone ``i`` only when the altitude ranges
  they fly through (from the current height to the goal's, :func:`altitude_gap`) come
  closer than 0.54 m plus :data:`VERTICAL_MARGIN`. So a drone passes over or under a
  neighbour far enough below or above, and two landmarks that overlap seen from above, at
  different heights, can both be covered. ORCA takes the slice of the two spheres at
  their gap as the combined radius; RRT* the full one (a cylinder), around the drones
  where they are and where they will be ``lookahead`` seconds on; Voronoi partitions
  the plane among all alive drones (one diagram per world, the paper's partition), so it
  is planar throughout. The drone scenarios have no obstacles; the map's border is a
  fence (:meth:`DronePlanner.fence`), since a drone that leaves the map crashes.
* **Control**: the planner's horizontal velocity is tracked by the Lee controller's
  velocity loop (target position: the drone's own ``(x, y)`` and the goal's altitude,
  target vertical velocity :data:`CLIMB_GAIN` × the altitude error). Horizontally the
  straight flight, :func:`~masp_lite.planners.controllers.arrive_velocity` with gain
  ``kx / kv`` and ``max_speed``, is then exactly the flight of the drones' ``h-greedy``
  (:class:`~masp_lite.policies.drones.DroneHungarianGreedy`: its position loop, saturated
  at ``max_speed``) away from the fence; the planners share all of it (assignment, fence,
  altitude, controller), so what one changes is only its planning.

ORCA re-solves every environment step; RRT* and Voronoi re-plan their paths every global
step (RRT* also when the next segment gets blocked), followed with
:func:`~masp_lite.planners.controllers.track_path`. Everything happens inside ``act``, so
the decision time measured around it is the full planning time per step. The particle
classes hand a drone world to these (``h-orca``, ``h-rrtstar``, ``h-voronoi``,
``h-bottleneck`` work on both worlds); options are the ``OPTIONS`` of each class, and (but for
``h-bottleneck``) ``goals`` and ``checkpoint``.
"""
from __future__ import annotations

import numpy as np
import torch

from ..algos.team import TeamAssignment
from ..envs.drone_model import COLLISION_RADIUS
from ..planners.controllers import GLOBAL_STEP, arrive_velocity, pad_paths, track_path
from ..planners.geometric import LeeController
from ..planners.orca import orca_halfplanes, solve_orca
from ..planners.rrt_star import plan_rrt_star, segments_blocked
from ..planners.voronoi import plan_voronoi
from .goal_sources import goal_source

__all__ = ["DronePlanner", "DroneHOrca", "DroneHRRTStar", "DroneHVoronoi", "DroneBottleneck", "altitude_gap",
           "VERTICAL_MARGIN", "CLIMB_GAIN", "FENCE_MARGIN", "FENCE_TIME"]

#: Altitude gap (m) beyond the spheres' contact below which two drones still count as able to
#: touch: in a hard turn a drone sinks by up to about 0.3 m (its thrust tilts with an attitude
#: that lags the command), while it holds its height within centimetres in straight flight.
VERTICAL_MARGIN = 0.25
#: Vertical velocity (1/s) asked per metre below or above the goal's altitude, on top of the
#: controller's position loop: the altitude loop becomes ``8 e_z + 4 v_z`` (damping 0.7)
#: instead of ``4 e_z + 4 v_z``, so a drone reaches its layer sooner and sinks less in turns;
#: on seeded drone-5/drone-20 runs it lowered the crashes of every planner here.
CLIMB_GAIN = 1.0
#: Distance (m) inside the map's border of the fence that no planned velocity crosses.
FENCE_MARGIN = 0.2
#: Time (s) in which a drone may close its distance to the fence: the speed towards a border
#: is at most (distance to the fence) / FENCE_TIME.
FENCE_TIME = 0.6


def _np(x):
    return x.detach().cpu().numpy().astype(np.float64) if torch.is_tensor(x) else np.asarray(x, np.float64)


def _slice(gap):
    """Horizontal distance at which two collision spheres ``gap`` apart in height touch."""
    return np.sqrt(np.maximum((2 * COLLISION_RADIUS) ** 2 - np.square(gap), 0.0))


def altitude_gap(z, goal_z) -> np.ndarray:
    """Smallest vertical distance (B, N, N) two drones can have while flying to their goals.

    Drone ``i`` flies through the altitudes between its height ``z`` (B, N) and its goal's
    ``goal_z`` (B, N); the gap of two drones is the distance between those two ranges
    (0 when they overlap). Two drones whose gap is at least ``2 · COLLISION_RADIUS`` never
    touch, whatever their horizontal paths.

    >>> altitude_gap(np.array([[1.5, 1.5]]), np.array([[1.0, 2.0]]))[0].tolist()
    [[0.0, 0.0], [0.0, 0.0]]
    >>> float(altitude_gap(np.array([[1.0, 2.0]]), np.array([[1.0, 2.0]]))[0, 0, 1])
    1.0
    """
    lo, hi = np.minimum(z, goal_z), np.maximum(z, goal_z)
    return np.maximum(0.0, np.maximum(lo[:, :, None], lo[:, None]) - np.minimum(hi[:, :, None], hi[:, None]))


class DronePlanner:
    """Shared base: (H) goals every global step, a planar ``desired_velocity`` → Lee controller."""

    #: Planner parameters accepted as keyword options, with their defaults.
    OPTIONS: dict = dict(max_speed=4.0)

    def __init__(self, world, seed: int = 0, team_protocol: str = "random_subset", goals: str = "hungarian",
                 checkpoint: str | None = None, **options):
        name = type(self).__name__
        if getattr(getattr(world, "scenario", None), "kind", None) != "drone":
            raise ValueError(f"{name}: expected a drone world (drone-* scenario), got scenario "
                             f"{getattr(getattr(world, 'scenario', None), 'name', None)!r}")
        unknown = sorted(set(options) - set(self.OPTIONS))
        if unknown:
            raise ValueError(f"{name}: unknown option(s) {unknown}; expected some of "
                             f"{sorted(self.OPTIONS) + ['checkpoint', 'goals', 'seed', 'team_protocol']}")
        self.world, self.scenario, self.seed = world, world.scenario, int(seed)
        self.opt = {**self.OPTIONS, **{k: type(self.OPTIONS[k])(v) for k, v in options.items()}}
        self.team = self.team_assignment(team_protocol)
        self.source = goal_source(goals, world, checkpoint)   # None: the (H) assignment above
        self.global_step = GLOBAL_STEP if self.source is None else self.source.global_step
        # DroneHungarianGreedy's controller: kx = kv = 4, the position loop critically damped
        self.controller = LeeController(kx=4.0, kv=4.0, max_speed=self.opt["max_speed"])
        self.gain = self.controller.kx / self.controller.kv   # its position loop as a velocity
        self.goal_index = None

    def team_assignment(self, team_protocol: str) -> TeamAssignment:
        return TeamAssignment(team_protocol, bool(self.scenario.varying), seed=self.seed)

    @property
    def assignment(self) -> torch.Tensor | None:
        """Goal index per drone (B, N) of the latest global step (-1: none); for playback."""
        return None if self.goal_index is None else torch.from_numpy(self.goal_index)

    def reset(self, obs) -> None:
        self.team.reset()
        if self.source is not None:
            self.source.reset(obs)
        self.goal_index = self.goal = None
        self.reset_planner(obs)

    def assign(self, obs) -> np.ndarray:
        """Goal index per drone (B, N), ``-1`` for none: the (H) assignment in 3-D, or the goal source's."""
        if self.source is not None:
            return self.source(obs).cpu().numpy()
        return self.team.assign(obs, self.assignment).cpu().numpy()

    def act(self, obs) -> torch.Tensor:
        t = obs["t"].cpu().numpy()
        pos, vel, alive = _np(obs["agent_pos"]), _np(obs["agent_vel"]), obs["alive"].cpu().numpy()
        due = (t % self.global_step == 0) if self.goal_index is not None else np.ones(len(t), bool)
        if due.any():
            idx = self.assign(obs)
            lms = _np(obs["landmark_pos"])
            goal = np.where((idx >= 0)[..., None], np.take_along_axis(lms, np.clip(idx, 0, None)[..., None], 1), pos)
            first = self.goal_index is None
            self.goal_index = idx if first else np.where(due[:, None], idx, self.goal_index)
            self.goal = goal if first else np.where(due[:, None, None], goal, self.goal)
        desired = self.fence(pos, self.desired_velocity(obs, pos, vel, self.goal, due))
        desired = np.where(alive[..., None], desired, 0.0)
        target_pos = np.concatenate([pos[..., :2], self.goal[..., 2:]], -1)   # hold (x, y), climb to the goal
        climb = CLIMB_GAIN * (self.goal[..., 2:] - pos[..., 2:])
        target_vel = np.concatenate([desired, climb], -1)
        cmd = self.controller(obs["agent_pos"], obs["agent_vel"], obs["agent_quat"], obs["agent_angvel"],
                              target_pos=torch.from_numpy(target_pos), target_vel=torch.from_numpy(target_vel))
        return cmd.to(obs["agent_pos"].device)

    def straight(self, pos, goal) -> np.ndarray:
        """Horizontal velocity of a straight flight to ``goal``: h-greedy's, (B, N, 2)."""
        return arrive_velocity(pos[..., :2], goal[..., :2], self.opt["max_speed"], self.gain)

    def fence_limits(self, pos) -> tuple[np.ndarray, np.ndarray]:
        """(B, N, 2) lowest and highest horizontal velocity the map's border allows.

        A drone whose centre leaves the map crashes. Towards each side the speed is at most
        its distance to a fence ``FENCE_MARGIN`` inside the border over ``FENCE_TIME``
        (negative beyond the fence: back inside), so a drone brakes before the border.
        """
        h = self.scenario.world_size / 2 - FENCE_MARGIN
        return (-h - pos[..., :2]) / FENCE_TIME, (h - pos[..., :2]) / FENCE_TIME

    def fence(self, pos, desired) -> np.ndarray:
        """``desired`` clipped to :meth:`fence_limits`."""
        lo, hi = self.fence_limits(pos)
        return np.clip(desired, lo, hi)

    def conflicts(self, obs, pos, goal) -> np.ndarray:
        """(B, N, N) bool: drone ``j`` can touch drone ``i`` (alive, not ``i``, altitude gap
        below ``2 · COLLISION_RADIUS + VERTICAL_MARGIN``)."""
        alive = obs["alive"].cpu().numpy()
        N = alive.shape[1]
        near = altitude_gap(pos[..., 2], goal[..., 2]) < 2 * COLLISION_RADIUS + VERTICAL_MARGIN
        return near & alive[:, None, :] & alive[:, :, None] & ~np.eye(N, dtype=bool)

    # --------------------------------------------------------------- planner
    def reset_planner(self, obs) -> None:
        """Clear per-episode planner state (paths)."""

    def desired_velocity(self, obs, pos, vel, goal, due) -> np.ndarray:
        """(B, N, 2) horizontal velocities to track; ``pos``, ``vel``, ``goal`` (B, N, 3)."""
        raise NotImplementedError


class DroneBottleneck(DronePlanner):
    """``h-bottleneck`` on drones: min–max goals every ``global_step`` steps, straight flights.

    The longest trip as short as possible (:func:`~masp_lite.algos.team.bottleneck`),
    re-solved every global step; shrunk teams re-solve over the unreached landmarks
    (``team_protocol="resolve"``, h-greedy's). The flight is the planners' straight one
    (:meth:`~DronePlanner.straight`, inside the fence), with no avoidance.
    """

    def __init__(self, world, global_step: int = GLOBAL_STEP, **options):
        if isinstance(global_step, bool) or not isinstance(global_step, int) or global_step < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        if options.get("goals", "hungarian") != "hungarian" or options.get("checkpoint") is not None:
            raise ValueError("h-bottleneck: its min-max assignment is its goal source (goals= and checkpoint= "
                             "are not options of it); for a straight flight to MASP's goals use h-greedy "
                             "with goals=masp")
        super().__init__(world, team_protocol="resolve", **options)
        self.global_step = global_step

    def team_assignment(self, team_protocol):
        return TeamAssignment(team_protocol, bool(self.scenario.varying), cost="bottleneck", seed=self.seed)

    def desired_velocity(self, obs, pos, vel, goal, due):
        return self.straight(pos, goal)


class DroneHOrca(DronePlanner):
    """(H)ORCA on drones: the straight flight's velocity made collision-free by ORCA each step.

    Neighbours are the ``max_neighbors`` nearest drones that can touch (see
    :meth:`~DronePlanner.conflicts`) within ``neighbor_dist``. The combined radius of a pair
    is the horizontal distance at which their collision spheres touch at their altitude gap
    less :data:`VERTICAL_MARGIN`, plus ``safety_margin`` for each — but no more than their
    two goals leave between them (landmarks may lie 0.59 m apart), and never less than
    the distance of contact at their gap, so that both can hover on their landmarks. The
    map's border enters as four hard lines (RVO2's obstacle lines): the fence limits of
    :meth:`~DronePlanner.fence_limits`. ``time_horizon`` (0.75 s) is longer than the
    particle world's 0.5 s, with which two drones closing head-on at 5 m/s react too late
    to turn (a drone's velocity lags its command by about 0.25 s); longer ones (1–1.5 s)
    make drones creep onto landmarks next to a hovering neighbour, so fewer are covered by
    the end of seeded drone-5 episodes. Deadlocks of two
    drones meeting head-on are broken as the particle (H)ORCA breaks them: a drone far from
    its goal that ORCA slows below ``stall`` × its preferred speed re-solves with its
    preferred velocity turned ``detour_deg`` degrees to its right.
    """

    OPTIONS = dict(time_horizon=0.75, neighbor_dist=6.0, max_neighbors=10, safety_margin=0.1, time_step=0.1,
                   max_speed=4.0, stall=0.25, detour_deg=60.0)

    def desired_velocity(self, obs, pos, vel, goal, due):
        o = self.opt
        pref = self.straight(pos, goal)
        out = self._orca(obs, pos, vel, goal, pref)
        speed, want = np.linalg.norm(out, axis=-1), np.linalg.norm(pref, axis=-1)
        far = np.linalg.norm(goal[..., :2] - pos[..., :2], axis=-1) > self.world.reach_distance
        stalled = far & (speed < o["stall"] * want)
        if stalled.any():
            a = -np.deg2rad(o["detour_deg"])
            turned = pref @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
            retry = self._orca(obs, pos, vel, goal, np.where(stalled[..., None], turned, pref))
            out = np.where(stalled[..., None], retry, out)
        return out

    def _orca(self, obs, pos, vel, goal, pref):
        o = self.opt
        B, N, _ = pos.shape
        k = max(min(int(o["max_neighbors"]), N - 1), 0)
        p2, v2 = pos[..., :2], vel[..., :2]
        dist = np.linalg.norm(p2[:, None] - p2[:, :, None], axis=-1)            # (B, N, N)
        dist = np.where(self.conflicts(obs, pos, goal), dist, np.inf)
        nb = np.argsort(dist, axis=-1)[..., :k]                                 # nearest first
        d = np.take_along_axis(dist, nb, -1)
        b = np.arange(B)[:, None, None]
        gap = np.take_along_axis(altitude_gap(pos[..., 2], goal[..., 2]), nb, -1)
        contact = _slice(gap)                                                   # touching at this gap
        safe = _slice(np.maximum(gap - VERTICAL_MARGIN, 0.0)) + 2 * o["safety_margin"]
        room = np.linalg.norm(goal[b, nb, :2] - goal[:, :, None, :2], axis=-1) - 0.02
        radius = np.minimum(safe, np.maximum(contact, room))                    # both may sit on their goals
        points, dirs = orca_halfplanes(p2[b, nb] - p2[:, :, None], v2[:, :, None] - v2[b, nb], v2[:, :, None],
                                       radius, 0.5, o["time_horizon"], o["time_step"])
        valid = d < o["neighbor_dist"]
        # the map's border: four hard lines first (RVO2's obstacle lines), v_x, v_y within the fence limits
        lo, hi = self.fence_limits(pos)
        zero = np.zeros_like(lo[..., 0])
        wall_p = np.stack([np.stack([hi[..., 0], zero], -1), np.stack([lo[..., 0], zero], -1),
                           np.stack([zero, hi[..., 1]], -1), np.stack([zero, lo[..., 1]], -1)], 2)
        wall_d = np.broadcast_to(np.array([[0.0, 1.0], [0.0, -1.0], [-1.0, 0.0], [1.0, 0.0]]), wall_p.shape)
        points, dirs = np.concatenate([wall_p, points], 2), np.concatenate([wall_d, dirs], 2)
        valid = np.concatenate([np.ones(valid.shape[:2] + (4,), bool), valid], 2)
        out = solve_orca(points.reshape(B * N, k + 4, 2), dirs.reshape(B * N, k + 4, 2),
                         valid.reshape(B * N, k + 4), pref.reshape(B * N, 2), o["max_speed"], n_obstacle_lines=4)
        return out.reshape(B, N, 2)


class _DronePathPlanner(DronePlanner):
    """Shared path state of RRT* and Voronoi: waypoints (B, N, P, 2) tracked by ``track_path``."""

    def reset_planner(self, obs):
        self.paths = None
        self.index = None

    def set_paths(self, new, which):
        """Store new waypoint rows for drones ``which`` (B, N) bool, restarting their index."""
        if self.paths is None:
            self.paths, self.index = new, np.zeros(which.shape, np.int64)
            return
        P = max(self.paths.shape[2], new.shape[2])
        self.paths = np.where(which[..., None, None], pad_paths(new, P), pad_paths(self.paths, P))
        self.index = np.where(which, 0, self.index)

    def track(self, pos):
        """Desired velocities along the paths: ``track_path``, no faster than the straight
        flight of the same length (``gain`` × the length left), so a drone brakes for its
        goal wherever the path bends before it."""
        B, N, P, _ = self.paths.shape
        desired, idx = track_path(pos[..., :2].reshape(B * N, 2), self.paths.reshape(B * N, P, 2),
                                  self.index.reshape(-1), switch_dist=self.opt["switch_dist"],
                                  max_speed=self.opt["max_speed"], gain=self.gain)
        self.index = idx = idx.reshape(B, N)
        nxt = np.take_along_axis(self.paths, idx[..., None, None].repeat(2, -1), 2)[:, :, 0]
        seg = np.linalg.norm(np.diff(self.paths, axis=2), axis=-1)                  # (B, N, P - 1)
        after = np.where(np.arange(P - 1) >= idx[..., None], seg, 0.0).sum(-1)
        left = np.linalg.norm(nxt - pos[..., :2], axis=-1) + after
        desired = desired.reshape(B, N, 2)
        speed = np.linalg.norm(desired, axis=-1)
        return desired * np.minimum(1.0, self.gain * left / np.maximum(speed, 1e-12))[..., None]


class DroneHRRTStar(_DronePathPlanner):
    """(H)RRT* on drones: per-drone RRT* paths in the plane around the drones that can touch it.

    Every drone plans its own tree (:func:`~masp_lite.planners.rrt_star.plan_rrt_star`, one
    row per drone) around the other drones, discs of radius ``2 · COLLISION_RADIUS + margin``
    where they are and where their velocity takes them in ``lookahead`` seconds (a drone at
    4 m/s covers a metre before it has turned; on seeded drone-20 runs this lowered the
    crashes), those that cannot touch it left out. It re-plans every global step and when
    its next segment gets blocked, and keeps its old path when that is still free and no
    longer (as the particle (H)RRT*).
    """

    OPTIONS = dict(samples=60, step_size=2.0, rewire_radius=3.0, goal_bias=0.2, margin=0.15, switch_dist=0.5,
                   lookahead=0.5, max_speed=4.0)

    def reset_planner(self, obs):
        super().reset_planner(obs)
        self._rng = np.random.default_rng(self.seed)

    def desired_velocity(self, obs, pos, vel, goal, due):
        o = self.opt
        B, N, _ = pos.shape
        # one planning row per drone: its start and goal, every drone as a circle, its own mask
        start, end = pos[..., :2].reshape(B * N, 1, 2), goal[..., :2].reshape(B * N, 1, 2)
        ahead = pos[..., :2] + vel[..., :2] * o["lookahead"]                    # where they will be
        centres = np.repeat(np.concatenate([pos[..., :2], ahead], 1), N, axis=0)  # (B N, 2 N, 2)
        radii = np.full(2 * N, 2 * COLLISION_RADIUS + o["margin"])
        mask = np.tile(self.conflicts(obs, pos, goal), 2).reshape(B * N, 2 * N)
        if self.paths is None:
            replan = np.ones((B, N), bool)
        else:
            goal_moved = np.abs(self.paths[:, :, -1] - goal[..., :2]).sum(-1) > 1e-9
            nxt = np.take_along_axis(self.paths, self.index[..., None, None].repeat(2, -1), 2)[:, :, 0]
            blocked = segments_blocked(start, nxt.reshape(B * N, 1, 2), centres, radii, mask, goal=end,
                                       margin=o["margin"]).reshape(B, N)
            replan = due[:, None] | goal_moved | blocked
        if replan.any():
            new = plan_rrt_star(start, end, centres, radii, mask, replan.reshape(B * N, 1), self._rng,
                                bounds=self.scenario.world_size / 2 - COLLISION_RADIUS - o["margin"],
                                samples=int(o["samples"]), step_size=o["step_size"],
                                rewire_radius=o["rewire_radius"], goal_bias=o["goal_bias"], margin=o["margin"],
                                previous=self._remaining(pos, goal))
            self.set_paths(new.reshape(B, N, *new.shape[2:]), replan)
        return self.track(pos)

    def _remaining(self, pos, goal):
        """The current paths from the current position on, one row per drone (None before the first plan)."""
        if self.paths is None:
            return None
        B, N, P, _ = self.paths.shape
        keep = np.arange(P)[None, None, :] >= self.index[..., None]
        rest = np.where(keep[..., None], self.paths, pos[:, :, None, :2])
        still = np.abs(self.paths[:, :, -1] - goal[..., :2]).sum(-1) <= 1e-9
        rest = np.where(still[..., None, None], rest, goal[:, :, None, :2].repeat(P, 2))
        return rest.reshape(B * N, 1, P, 2)


class DroneHVoronoi(_DronePathPlanner):
    """(H)Voronoi on drones: shortest routes along the safe edges of the drones' Voronoi
    diagram in the plane (every alive drone a generator of radius ``COLLISION_RADIUS``),
    re-planned every global step."""

    OPTIONS = dict(margin=0.1, switch_dist=0.5, max_speed=4.0)

    def desired_velocity(self, obs, pos, vel, goal, due):
        if self.paths is None or due.any():
            B, N, _ = pos.shape
            which = np.ones((B, N), bool) if self.paths is None else np.broadcast_to(due[:, None], (B, N)).copy()
            new = plan_voronoi(pos[..., :2], goal[..., :2], np.zeros((B, 0, 2)), obs["alive"].cpu().numpy(),
                               agent_radius=COLLISION_RADIUS, obstacle_radius=COLLISION_RADIUS,
                               half_size=self.scenario.world_size / 2, margin=self.opt["margin"])
            self.set_paths(new, which)
        return self.track(pos)
