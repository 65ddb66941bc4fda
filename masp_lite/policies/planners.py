"""The (H) planning baselines as policies: Hungarian goal assignment + a planner + one controller.

The paper's planning baselines (section "Baselines": "(H)ORCA", "(H)RRT*", "(H)Voronoi")
assign goals centrally with the Hungarian algorithm and let a classical planner drive each
agent to its goal. All three share :class:`HungarianPlanner`:

* **Goal assignment, every global step** (3 environment steps, the paper's Goal Matcher
  period): :func:`masp_lite.algos.assignment.hungarian` of the alive agents to all
  landmarks for a fixed team (success is judged with every landmark covered at the end);
  for varying teams the paper's rule, "a random subset of unreached goals matching the
  agent count at each global step" (:func:`~masp_lite.algos.assignment.hungarian_random_subset`);
  ``team_protocol="sequential"`` takes the paper's other account instead (assign once
  when the team shrinks, hand on leftover goals as agents reach theirs;
  :class:`~masp_lite.algos.team.TeamAssignment`).
  An agent left without a goal (more agents than unreached landmarks) holds its position.
* **Planning**, in the subclass's :meth:`~HungarianPlanner.desired_velocity`: ORCA every
  environment step; RRT* and Voronoi paths every global step (RRT* also when blocked),
  followed with :func:`~masp_lite.planners.controllers.track_path`.
* **Control**: :func:`~masp_lite.planners.controllers.velocity_to_action`, the same for all.

Everything happens inside ``act``, so the decision time measured around it is the full
planning time per environment step. Policies are built by the registry as
``factory(world, **options)``; options are the planner parameters listed in ``OPTIONS``.

:func:`split_collisions` separates a step's collision count into agent–agent and
agent–obstacle contacts, from the world state (the bench reports the obstacle share).
"""
from __future__ import annotations

import numpy as np
import torch

from ..algos.team import TeamAssignment
from ..planners.controllers import GLOBAL_STEP, MAX_SPEED, arrive_velocity, pad_paths, track_path, velocity_to_action
from ..planners.orca import orca_velocities
from ..planners.rrt_star import plan_rrt_star, segments_blocked
from ..planners.voronoi import plan_voronoi

__all__ = ["HungarianPlanner", "HOrca", "HRRTStar", "HVoronoi", "split_collisions", "GLOBAL_STEP"]



def _np(x):
    return x.detach().cpu().numpy() if torch.is_tensor(x) else np.asarray(x)


class HungarianPlanner:
    """Shared base: Hungarian goals every global step, then ``desired_velocity`` → actions."""

    #: Planner parameters accepted as keyword options, with their defaults.
    OPTIONS: dict = {}
    def __init__(self, world, seed: int = 0, team_protocol: str = "random_subset", **options):
        unknown = sorted(set(options) - set(self.OPTIONS))
        if unknown:
            raise ValueError(f"{type(self).__name__}: unknown option(s) {unknown}; expected some of "
                             f"{sorted(self.OPTIONS) + ['seed', 'team_protocol']}")
        if getattr(world.scenario, "kind", "particle") != "particle":
            raise ValueError(f"{type(self).__name__}: expected a particle world (mpe-*), "
                             f"got scenario {world.scenario.name!r}")
        self.world, self.scenario, self.seed = world, world.scenario, int(seed)
        self.opt = {**self.OPTIONS, **{k: type(self.OPTIONS[k])(v) for k, v in options.items()}}
        self.team = TeamAssignment(team_protocol, bool(world.scenario.varying), seed=self.seed)
        self.goal_index = None

    # ------------------------------------------------------------ assignment
    def reset(self, obs) -> None:
        self.team.reset()
        self.goal_index = None
        self.reset_planner(obs)

    def assign(self, obs) -> np.ndarray:
        """Goal index per agent (B, N), ``-1`` for none: the paper's (H) assignment."""
        current = None if self.goal_index is None else torch.from_numpy(self.goal_index)
        return _np(self.team.assign(obs, current))

    @property
    def assignment(self) -> torch.Tensor | None:
        """Goal index per agent (B, N) of the latest global step (-1: none); for playback."""
        return None if self.goal_index is None else torch.from_numpy(self.goal_index)

    def goals(self, obs) -> np.ndarray:
        """Goal position per agent (B, N, 2); an agent without a goal targets where it is."""
        pos, lms = _np(obs["agent_pos"]).astype(np.float64), _np(obs["landmark_pos"]).astype(np.float64)
        idx = self.goal_index
        g = np.take_along_axis(lms, np.clip(idx, 0, None)[..., None], 1)
        return np.where((idx >= 0)[..., None], self.standoff(g, _np(obs["obstacle_pos"])), pos)

    def standoff(self, goals, obstacles, margin: float = 0.06) -> np.ndarray:
        """Move goal points that sit too close to an obstacle just clear of it.

        A landmark may lie as close as ``r_landmark + r_obstacle`` to an obstacle, where an
        agent on it would touch the obstacle. The target point is pushed straight away from
        the nearest such obstacle to ``r_agent + r_obstacle + margin`` — at most 0.1 m for the
        paper's radii, well inside the ``r_agent + r_landmark`` that counts as reached.
        """
        sc = self.scenario
        if obstacles.shape[1] == 0:
            return goals
        off = goals[:, :, None] - obstacles[:, None].astype(np.float64)          # (B, N, K, 2)
        dist = np.linalg.norm(off, axis=-1)
        k = dist.argmin(-1)[..., None]
        d = np.take_along_axis(dist, k, -1)[..., 0]
        need = sc.agent_radius + sc.obstacle_radius + margin
        push = (d < need) & (need - d < sc.reach_distance - 0.01)
        unit = np.take_along_axis(off, k[..., None], 2)[:, :, 0] / np.maximum(d, 1e-9)[..., None]
        return np.where(push[..., None], goals + unit * (need - d)[..., None], goals)

    def act(self, obs) -> torch.Tensor:
        t = _np(obs["t"])
        due = (t % GLOBAL_STEP == 0) if self.goal_index is not None else np.ones(len(t), bool)
        if due.any():
            new = self.assign(obs)
            self.goal_index = new if self.goal_index is None else np.where(due[:, None], new, self.goal_index)
        desired = self.desired_velocity(obs, self.goals(obs), due)
        desired = np.where(_np(obs["alive"])[..., None], desired, 0.0)
        act = velocity_to_action(_np(obs["agent_vel"]), desired)
        return torch.from_numpy(act).to(obs["agent_pos"].device)

    # --------------------------------------------------------------- planner
    def reset_planner(self, obs) -> None:
        """Clear per-episode planner state (paths)."""

    def desired_velocity(self, obs, goals: np.ndarray, due: np.ndarray) -> np.ndarray:
        """(B, N, 2) velocities the controller should track; ``due`` (B,) marks global steps."""
        raise NotImplementedError


class HOrca(HungarianPlanner):
    """(H)ORCA: preferred velocity straight to the goal, made collision-free by ORCA each step.

    ORCA is deterministic and symmetric, so two agents meeting exactly head-on can both stop
    (and discrete actions cannot produce the tiny sideways drift that would free them).
    As RVO2's examples perturb preferred velocities against such deadlocks, an agent that is
    still far from its goal while ORCA slows it below ``stall`` × its preferred speed
    re-solves with its preferred velocity turned ``detour_deg`` degrees to its right
    (everyone keeps right, so the pair passes).
    """

    OPTIONS = dict(time_horizon=0.5, time_horizon_obst=0.3, neighbor_dist=3.0, max_neighbors=8,
                   max_obstacles=4, safety_margin=0.04, max_speed=MAX_SPEED, stall=0.25, detour_deg=60.0)

    def desired_velocity(self, obs, goals, due):
        o = self.opt
        pos = _np(obs["agent_pos"]).astype(np.float64)
        pref = arrive_velocity(pos, goals, o["max_speed"])
        out = self._orca(obs, pos, pref)
        speed, want = np.linalg.norm(out, axis=-1), np.linalg.norm(pref, axis=-1)
        far = np.linalg.norm(goals - pos, axis=-1) > self.scenario.reach_distance
        stalled = far & (speed < o["stall"] * want)
        if stalled.any():
            a = -np.deg2rad(o["detour_deg"])
            turned = pref @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
            out = np.where(stalled[..., None], self._orca(obs, pos, np.where(stalled[..., None], turned, pref)), out)
        return out

    def _orca(self, obs, pos, pref):
        o, sc = self.opt, self.scenario
        return orca_velocities(pos, _np(obs["agent_vel"]), pref, _np(obs["obstacle_pos"]),
                               agent_radius=sc.agent_radius, obstacle_radius=sc.obstacle_radius,
                               alive=_np(obs["alive"]), max_speed=o["max_speed"],
                               time_horizon=o["time_horizon"], time_horizon_obst=o["time_horizon_obst"],
                               neighbor_dist=o["neighbor_dist"], max_neighbors=int(o["max_neighbors"]),
                               max_obstacles=int(o["max_obstacles"]), safety_margin=o["safety_margin"])


class _PathPlanner(HungarianPlanner):
    """Shared path state of RRT* and Voronoi: waypoints (B, N, P, 2) tracked by ``track_path``."""

    def reset_planner(self, obs):
        self.paths = None
        self.index = None

    def circles(self, obs):
        """Planning-time obstacles per episode: (B, K + N, 2) centres, (K + N,) radii, (B, K + N) mask.

        Obstacles are inflated by the agent radius and a margin; the other alive agents are
        obstacles too (at their current position), inflated the same way.
        """
        sc, m = self.scenario, self.opt["margin"]
        obst = _np(obs["obstacle_pos"]).astype(np.float64)
        pos = _np(obs["agent_pos"]).astype(np.float64)
        centres = np.concatenate([obst, pos], 1)
        radii = np.concatenate([np.full(obst.shape[1], sc.obstacle_radius + sc.agent_radius + m),
                                np.full(pos.shape[1], 2 * sc.agent_radius + m)])
        mask = np.concatenate([np.ones(obst.shape[:2], bool), _np(obs["alive"])], 1)
        return centres, radii, mask

    def set_paths(self, new_paths, which):
        """Store new waypoint rows for agents ``which`` (B, N) bool, restarting their index."""
        B, N = which.shape
        if self.paths is None:
            self.paths = new_paths
            self.index = np.zeros((B, N), np.int64)
            return
        P = max(self.paths.shape[2], new_paths.shape[2])
        old, new = pad_paths(self.paths, P), pad_paths(new_paths, P)
        self.paths = np.where(which[..., None, None], new, old)
        self.index = np.where(which, 0, self.index)

    def track(self, obs):
        pos = _np(obs["agent_pos"]).astype(np.float64)
        B, N, P, _ = self.paths.shape
        desired, idx = track_path(pos.reshape(B * N, 2), self.paths.reshape(B * N, P, 2),
                                  self.index.reshape(-1), max_speed=self.opt["max_speed"])
        self.index = idx.reshape(B, N)
        return desired.reshape(B, N, 2)


class HRRTStar(_PathPlanner):
    """(H)RRT*: per-agent RRT* paths around obstacles and agents, re-planned every global
    step or when the next segment is blocked; a better old path is kept (paths are reused)."""

    OPTIONS = dict(samples=60, step_size=1.0, rewire_radius=1.5, goal_bias=0.2, margin=0.1,
                   max_speed=MAX_SPEED)

    def reset_planner(self, obs):
        super().reset_planner(obs)
        self._rng = np.random.default_rng(self.seed)

    def desired_velocity(self, obs, goals, due):
        pos = _np(obs["agent_pos"]).astype(np.float64)
        centres, radii, mask = self.circles(obs)
        B, N, _ = pos.shape
        if self.paths is None:
            replan = np.ones((B, N), bool)
        else:
            goal_moved = np.abs(self.paths[:, :, -1] - goals).sum(-1) > 1e-9
            nxt = np.take_along_axis(self.paths, self.index[..., None, None].repeat(2, -1), 2)[:, :, 0]
            blocked = segments_blocked(pos, nxt, centres, radii, mask, self_index=self._self_index(B, N),
                                       goal=goals, margin=self.opt["margin"])
            replan = due[:, None] | goal_moved | blocked
        if replan.any():
            o = self.opt
            new = plan_rrt_star(pos, goals, centres, radii, mask, replan, self._rng,
                                self_index=self._self_index(B, N), bounds=self.scenario.world_size / 2,
                                samples=int(o["samples"]), step_size=o["step_size"],
                                rewire_radius=o["rewire_radius"], goal_bias=o["goal_bias"], margin=o["margin"],
                                previous=self._remaining(pos, goals))
            self.set_paths(new, replan)
        return self.track(obs)

    def _self_index(self, B, N):
        """Column of each agent itself among the planning circles (it is not its own obstacle)."""
        return np.broadcast_to(self.world.num_obstacles + np.arange(N), (B, N))

    def _remaining(self, pos, goals):
        """The current paths from the current position on, for reuse (None before the first plan)."""
        if self.paths is None:
            return None
        B, N, P, _ = self.paths.shape
        keep = np.arange(P)[None, None, :] >= self.index[..., None]
        rest = np.where(keep[..., None], self.paths, pos[:, :, None])
        still = np.abs(self.paths[:, :, -1] - goals).sum(-1) <= 1e-9
        return np.where(still[..., None, None], rest, goals[:, :, None].repeat(P, 2))


class HVoronoi(_PathPlanner):
    """(H)Voronoi: shortest route along safe Voronoi edges of agents and obstacles, every global step."""

    OPTIONS = dict(margin=0.05, max_speed=MAX_SPEED)

    def desired_velocity(self, obs, goals, due):
        if self.paths is None or due.any():
            which = np.ones(goals.shape[:2], bool) if self.paths is None else \
                np.broadcast_to(due[:, None], goals.shape[:2]).copy()
            sc = self.scenario
            new = plan_voronoi(_np(obs["agent_pos"]).astype(np.float64), goals,
                               _np(obs["obstacle_pos"]).astype(np.float64), _np(obs["alive"]),
                               agent_radius=sc.agent_radius, obstacle_radius=sc.obstacle_radius,
                               half_size=sc.world_size / 2, margin=self.opt["margin"])
            self.set_paths(new, which)
        return self.track(obs)


def split_collisions(obs, scenario) -> tuple[torch.Tensor, torch.Tensor]:
    """Contacts in the current state, split: (agent–agent pairs (B,), agent–obstacle pairs (B,)).

    Uses the world's own contact rule (alive agents, centres closer than the radii sum), so
    the two parts add up to ``info["collisions"]``.
    """
    pos, alive = obs["agent_pos"], obs["alive"]
    N = pos.shape[1]
    d = torch.cdist(pos, pos)
    both = alive[:, :, None] & alive[:, None, :] & torch.ones(N, N, dtype=torch.bool, device=pos.device).triu(1)
    aa = ((d < 2 * scenario.agent_radius) & both).sum((1, 2))
    if obs["obstacle_pos"].shape[1]:
        do = torch.cdist(pos, obs["obstacle_pos"])
        ao = ((do < scenario.agent_radius + scenario.obstacle_radius) & alive[:, :, None]).sum((1, 2))
    else:
        ao = torch.zeros_like(aa)
    return aa, ao
