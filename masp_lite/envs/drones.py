"""The batched quadrotor world: ``num_envs`` MuJoCo episodes of N Hummingbirds.

The paper's second testbed (section "Experiments — OmniDrones") on a CPU: N drones must
cover N landmarks (virtual balls of radius 0.05 m) in a 3-D flight volume; the action is
the throttle command of each motor; a collision is a crash. The drone and its rotor model
are described in :mod:`masp_lite.envs.drone_model`.

Interface: the same as :class:`~masp_lite.envs.particle.ParticleWorld`, in 3-D.

=====================  ===================================================================
``reset(seed, options, env_ids)``  new episodes; ``options`` may fix ``agent_pos`` (N, 3),
                       ``agent_vel`` (N, 3), ``agent_quat`` (N, 4, w x y z), ``agent_angvel``
                       (N, 3, body frame), ``landmark_pos`` (N, 3), ``keep`` (N,) bool
``step(actions)``      ``actions`` float (B, N, 4) motor commands in [−1, 1] → (obs, info)
obs                    ``agent_pos``/``agent_vel`` (B, N, 3) world frame, ``agent_quat``
                       (B, N, 4), ``agent_angvel`` (B, N, 3), ``throttle`` (B, N, 4),
                       ``landmark_pos`` (B, N, 3), ``obstacle_pos`` (B, 0, 3), ``alive``,
                       ``covered``, ``reached`` (B, N), ``t`` (B,)
info                   ``covered``, ``reached``, ``collisions`` (B,), ``agent_collisions``
                       (B, N), ``alive``, ``done``, ``t`` — the particle world's keys
=====================  ===================================================================

Choices (the paper leaves them open):

* **Flight volume.** The map is ``[-ws/2, ws/2]²`` (``ws = world_size``) from the floor
  (z = 0) to ``CEILING`` = 3 m. Drones spawn hovering at ``FLIGHT_HEIGHT`` = 1.5 m, at
  least ``2·COLLISION_RADIUS + 0.05`` m apart; landmarks anywhere with z ∈ [1, 2] m, as far
  apart from one another, so that two drones can hover on two landmarks without touching.
  Only drawn positions are kept apart: a given ``agent_pos`` may put drones in contact
  (they crash in the first step), as the particle world lets given agents overlap.
  Rotors start at the hover throttle.
* **Reached (3-D).** A landmark is covered when an alive drone's centre is within
  ``reach_distance = ARM_LENGTH + landmark_radius`` = 0.22 m of its centre: the ball touches
  the disc swept by the arms (the drone presets set ``agent_radius`` to the arm length,
  so ``Scenario.reach_distance`` says the same).
* **Crashes.** A drone crashes when MuJoCo reports a contact of its collision sphere (radius
  ``COLLISION_RADIUS`` = 0.27 m, or the scenario's ``collision_radius``, which also spaces the
  spawns) with another drone or the floor during any physics substep of the step, or when it leaves the
  flight volume. ``collisions`` counts the events of the step: drone–drone pairs + floor
  contacts + exits, among drones alive before the step; ``agent_collisions`` the same per
  drone. A crashed drone is no longer ``alive``: it neither acts, collides nor covers
  landmarks (what it reached stays reached).
* **Leaving.** A drone that is not alive (crashed, or dropped when the team shrinks after
  ``change_step``, as in the particle world) leaves the physics: it is parked, motors off,
  at its own spot high above the map, so it touches nothing; its observed state stays the
  one it had when it left.

Physics. Several worlds (``num_envs`` > 1) are stepped by ``mujoco.batch.Batch`` (one
model, one state row per world, stepped in C on ``threads`` threads); one world (the
PettingZoo face) is one ``MjData`` stepped by ``mujoco.mj_step``. The two paths give the
same numbers (a test checks them against each other). Internal state is numpy (float64,
MuJoCo's); observations are torch tensors on ``device``, never written after they are
handed out, so a caller may keep them.

Speed. The rest of a step is a fixed cost per call, so ``step`` makes few numpy calls:
actions become thrusts in place in preallocated arrays, the crash test is one
conservative bounds check (the exact one runs only when it or a contact sensor fires),
tensors of arrays that change only on events are made once per event, and the coverage
test is skipped while provably nothing is covered (``_check_coverage``; the answer is the
same, bit for bit). ``python -m masp_lite bench drones`` measures the overhead against raw
``mj_step``.
"""
from __future__ import annotations

import json

import mujoco
import mujoco.batch
import numpy as np
import torch

from .base import BatchedWorld
from .checks import check_seed, reset_options
from .drone_model import ARM_LENGTH, COLLISION_RADIUS, HOVER_COMMAND, HUMMINGBIRD, MAX_THRUST, SUBSTEPS, build_xml
from .scenarios import Scenario

__all__ = ["DroneWorld", "FLIGHT_HEIGHT", "CEILING", "LANDMARK_HEIGHTS"]

FLIGHT_HEIGHT = 1.5
CEILING = 3.0
LANDMARK_HEIGHTS = (1.0, 2.0)
_GAP = 0.05
_PARK_HEIGHT = 100.0
_EVENT_KEYS = ("alive", "landmark_pos", "collisions", "agent_collisions", "covered", "reached", "not_done")
_OPTIONS = {"agent_pos": 3, "agent_vel": 3, "agent_quat": 4, "agent_angvel": 3, "landmark_pos": 3}


class DroneWorld(BatchedWorld):
    """``num_envs`` independent quadrotor navigation episodes stepped together."""

    kind = "drone"
    reset_options = _OPTIONS

    def __init__(self, scenario: str | Scenario = "drone-5", num_envs: int = 1,
                 device: str | torch.device = "cpu", seed: int | None = None,
                 dtype: torch.dtype = torch.float32, threads: int = 1, **overrides):
        sc = self._setup(scenario, num_envs, device, dtype, overrides)
        self.reach_distance = ARM_LENGTH + sc.landmark_radius
        r = self.collision_radius = COLLISION_RADIUS if sc.collision_radius is None else sc.collision_radius
        half = sc.world_size / 2
        if half < r + _GAP:
            raise ValueError(f"world_size: expected at least {2 * (r + _GAP):g} m for drones")
        self._rng = np.random.default_rng(check_seed(seed))
        self.model = mujoco.MjModel.from_xml_string(self.model_xml())
        B, N = self.num_envs, self.num_agents
        if B == 1:  # one world: one MjData stepped by mj_step (see the module docstring)
            self.batch, self._data = None, mujoco.MjData(self.model)
            self._qpos, self._qvel, self._ctrl = self._data.qpos[None], self._data.qvel[None], self._data.ctrl[None]
            self._sensordata = self._data.sensordata  # a view: the live sensor values of the MjData
        else:
            self.batch, self._data = mujoco.batch.Batch(self.model, B, nthread=int(threads)), None
            self._qpos, self._qvel, self._ctrl = (self.batch.bind(k) for k in ("qpos", "qvel", "ctrl"))
        self._park = np.zeros((N, 7))
        self._park[:, 0], self._park[:, 2], self._park[:, 3] = 3 * r * np.arange(N), _PARK_HEIGHT, 1
        self.throttle = np.zeros((B, N, 4))
        self._frozen = np.zeros((B, N, 13))
        self.alive = np.ones((B, N), bool)
        self._keep = np.ones((B, N), bool)
        self.t = np.zeros(B, np.int64)
        self._t_max = 0  # self.t.max(), kept as an int
        self.reached = np.zeros((B, N), bool)
        self.landmark_pos = np.zeros((B, N, 3))
        self.collisions = np.zeros(B, np.int64)
        self.agent_collisions = np.zeros((B, N), np.int64)
        self._rec = {"sensordata": np.zeros((B, SUBSTEPS, self.model.nsensordata))}
        # views of the state rows (or of the MjData) and scratch arrays that step() reuses
        self._q3, self._v3 = self._qpos.reshape(B, N, 7), self._qvel.reshape(B, N, 6)
        self._ctrl3 = self._ctrl.reshape(B, N, 4)
        for view, owner in ((self._q3, self._qpos), (self._v3, self._qvel), (self._ctrl3, self._ctrl)):
            assert np.shares_memory(view, owner)
        self._pos = self._q3[..., :3]
        self._cmd = np.zeros((B, N, 4))
        self._pos_abs, self._outside = np.zeros((B, N, 3)), np.zeros((B, N, 3), bool)
        self._limits = np.array([half, half, CEILING])
        self._no_obstacles = torch.zeros(B, 0, 3, dtype=dtype, device=self.device)
        self._events = {}  # tensors of the arrays that change only on events: see _event_tensors
        self._np_dtype = np.float32 if dtype == torch.float32 else np.float64
        self._ref_pos, self._skin = None, 0.0  # see _check_coverage
        self._everyone = True  # every drone of every episode is still flying
        self._no_counts = True  # collisions and agent_collisions are all zero
        self.reset()

    def model_xml(self) -> str:
        """The MJCF this world compiles: :func:`~masp_lite.envs.drone_model.build_xml` with its collision
        radius. A subclass may change the drones' collision shape here (only the crash test reads it)."""
        return build_xml(self.num_agents, self.collision_radius)

    # ------------------------------------------------------------------ reset
    def _option_bounds(self, name):
        """Positions inside the flight volume (above the floor, below ``CEILING``, over the map):
        a start outside it is a crash before the first step, and MuJoCo would silently reset a
        body sent far away. Velocities below 100 m/s and body rates below 1000 rad/s."""
        if name in ("agent_pos", "landmark_pos"):
            half = self.scenario.world_size / 2
            return np.array([-half, -half, 1e-6]), np.array([half, half, CEILING])
        limit = {"agent_vel": 100.0, "agent_angvel": 1000.0}.get(name, np.inf)
        return np.array(-limit), np.array(limit)

    def reset(self, seed: int | None = None, options: dict | None = None, env_ids=None) -> dict[str, torch.Tensor]:
        """Start new episodes (all, or ``env_ids``) and return the observation (see module doc)."""
        if seed is not None:
            self._rng = np.random.default_rng(check_seed(seed))
        N = self.num_agents
        ids = self._env_ids(env_ids)
        n = len(ids)
        options = reset_options(options)
        given = self._start_state(options, n)
        if n == 0:  # an empty id list or a mask with nothing marked: nothing to start
            return self.observe()
        r = self.collision_radius + _GAP / 2
        if "agent_pos" in given:
            pos = given["agent_pos"]
        else:
            pos = self._sample(n, r, (FLIGHT_HEIGHT, FLIGHT_HEIGHT))
        lms = given["landmark_pos"] if "landmark_pos" in given else self._sample(n, r, LANDMARK_HEIGHTS)
        if "agent_pos" in given:  # drawn positions are apart already; given ones may touch (a crash)
            d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1) + np.eye(N) * 1e9
            if (d == 0).any():
                raise ValueError("reset options: two drones at the same point; expected distinct positions "
                                 "(drones may overlap: they collide and crash in the first step)")
        quat = given.get("agent_quat", np.broadcast_to([1.0, 0, 0, 0], (n, N, 4)))
        norm = np.linalg.norm(quat, axis=-1, keepdims=True)
        if (norm < 1e-9).any():
            raise ValueError("reset option 'agent_quat': expected non-zero quaternions (w, x, y, z)")
        q = np.concatenate([pos, quat / norm], axis=-1)
        v = np.concatenate([given.get("agent_vel", np.zeros((n, N, 3))),
                            given.get("agent_angvel", np.zeros((n, N, 3)))], axis=-1)
        if self._data is None:
            self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        elif n:
            mujoco.mj_resetData(self.model, self._data)  # what Batch.reset does to a state row
        self._qpos[ids] = q.reshape(n, -1)
        self._qvel[ids] = v.reshape(n, -1)
        if self._data is None:
            self.batch.forward(ids)
        elif n:
            mujoco.mj_forward(self.model, self._data)
        self.throttle = self.throttle.copy()
        self.throttle[ids] = np.sqrt((HOVER_COMMAND + 1) / 2)
        self._ctrl[ids] = np.square(self.throttle[ids]).reshape(n, -1) * MAX_THRUST
        self.landmark_pos = self.landmark_pos.copy()
        self.landmark_pos[ids] = lms
        self.alive = self.alive.copy()
        self.alive[ids] = True
        self._everyone = bool(self.alive.all())
        self._keep[ids] = self._team_mask(n, options.get("keep"))
        self.t, self.reached = self.t.copy(), self.reached.copy()
        self.collisions, self.agent_collisions = self.collisions.copy(), self.agent_collisions.copy()
        self.t[ids] = 0
        self._t_max = int(self.t.max())
        self.reached[ids] = False
        self.collisions[ids] = 0
        self.agent_collisions[ids] = 0
        self._no_counts = not self.collisions.any()  # every count is zero
        self._events.clear()
        self._ref_pos = None  # drones and landmarks moved: the next coverage test is exact
        self._update_coverage()
        return self.observe()

    def _random_order(self, n) -> np.ndarray:
        return self._rng.random((n, self.num_agents)).argsort(axis=1)

    def _sample(self, n, radius, heights) -> np.ndarray:
        """Rejection-sample N points per episode, pairwise at least ``2 * radius`` apart."""
        N, half = self.num_agents, self.scenario.world_size / 2 - self.collision_radius - _GAP
        out = np.zeros((n, N, 3))

        def draw(m):
            return np.concatenate([self._rng.uniform(-half, half, (m, 2)), self._rng.uniform(*heights, (m, 1))], axis=1)

        def clear(todo, cand, i):
            return (np.linalg.norm(out[todo, :i] - cand[:, None], axis=-1) >= 2 * radius).all(axis=1)

        return self._place(out, draw, clear, f"{N} drones {2 * radius:.2f} m apart")

    # ------------------------------------------------------------------- step
    def step(self, actions) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """Advance every episode by one control step (``SUBSTEPS`` MuJoCo steps)."""
        x = self._actions(actions)  # the commands, in the scratch array self._cmd
        if self._t_max >= self.horizon:
            raise ValueError(f"episode over (horizon {self.horizon} reached); expected reset() before step()")
        B, N, alive, everyone = self.num_envs, self.num_agents, self.alive, self._everyone
        # rotor model: target throttle sqrt((c+1)/2), first-order lag, thrust = throttle² f_max
        x += 1.0
        x *= 0.5
        np.sqrt(x, out=x)
        x -= self.throttle
        x *= HUMMINGBIRD["rotor_lag"]
        self.throttle = throttle = x + self.throttle
        if not everyone:
            throttle *= alive[..., None]
            gone = ~alive  # park whoever left: zero velocity, own spot far above the map
            self._q3[gone] = np.broadcast_to(self._park, (B, N, 7))[gone]
            self._v3[gone] = 0.0
        np.multiply(throttle, throttle, out=self._ctrl3)
        self._ctrl3 *= MAX_THRUST
        rec = self._physics()
        self.t = self.t + 1
        self._t_max += 1
        leaving = None
        # crashes: a contact sensor fired, or a drone is out of the volume (a conservative test
        # on |position| first; parked drones fail it, so the exact test runs once one has left)
        np.greater(np.abs(self._pos, out=self._pos_abs), self._limits, out=self._outside)
        if rec.any() or self._outside.any():
            pos, half = self._pos, self.scenario.world_size / 2
            sens = rec.max(axis=1)  # contacts (B, 2N): [any, floor] per drone, max over substeps
            out = (np.abs(pos[..., :2]) > half).any(-1) | (pos[..., 2] > CEILING)
            touch_any, touch_floor = sens[:, 0::2], sens[:, 1::2]
            drone_contacts = (touch_any - touch_floor) * alive
            self.agent_collisions = ((drone_contacts + touch_floor + out) * alive).astype(np.int64)
            self.collisions = (np.rint(drone_contacts.sum(1) / 2)
                               + ((touch_floor + out) * alive).sum(1)).astype(np.int64)
            self._events.pop("collisions", None)
            self._no_counts = False
            leaving = alive & (self.agent_collisions > 0)
        elif not self._no_counts:  # counts of an earlier step: zero them
            self.collisions, self.agent_collisions = np.zeros(B, np.int64), np.zeros((B, N), np.int64)
            self._events.pop("collisions", None)
            self._no_counts = True
        if self.scenario.varying and (self.t == self.scenario.change_step).any():
            drop = alive & ~self._keep & (self.t == self.scenario.change_step)[:, None]
            leaving = drop if leaving is None else leaving | drop
        if leaving is not None and leaving.any():
            self._frozen[leaving] = self._state()[leaving]
            self.alive = alive & ~leaving
            self._events.pop("alive", None)
            self._everyone = False
        self._update_coverage()
        return self.observe(), self.info()

    def _physics(self) -> np.ndarray:
        """Run ``SUBSTEPS`` MuJoCo steps of every world; the contact sensors after each, (B, SUBSTEPS, 2N)."""
        rec = self._rec["sensordata"]
        if self._data is None:
            return self.batch.rollout(SUBSTEPS, record=("sensordata",), out=self._rec)["sensordata"]
        model, data, sensors, row = self.model, self._data, self._sensordata, rec[0]
        for k in range(SUBSTEPS):
            mujoco.mj_step(model, data)
            row[k] = sensors
        return rec

    def _actions(self, actions) -> np.ndarray:
        """Validate ``actions``; return them as float64 in the scratch array ``self._cmd``."""
        actions = self._check_actions(actions, integer=False, tail=(4,))
        if torch.is_tensor(actions):
            if actions.requires_grad:
                actions = actions.detach()
            actions = (actions if actions.device.type == "cpu" else actions.cpu()).numpy()
        a = self._cmd
        a[...] = actions  # float64, as MuJoCo computes
        if not np.abs(a).max() <= 1.0:  # one reduction in the common case; NaN fails it too
            if not np.isfinite(a).all():
                raise ValueError("actions: expected finite motor commands, got NaN or inf")
            raise ValueError(f"actions: expected motor commands in [-1, 1], got values in "
                             f"[{a.min():.3g}, {a.max():.3g}]")
        return a

    def _state(self) -> np.ndarray:
        """(B, N, 13) of the physics: position, quaternion (w x y z), linear velocity, body angular velocity."""
        return np.concatenate([self._q3, self._v3], axis=-1)

    @property
    def state(self) -> np.ndarray:
        """(B, N, 13) as observed: the physics state, or where a drone left the one it had then."""
        s = self._state()
        return s if self._everyone else np.where(self.alive[..., None], s, self._frozen)

    def _update_coverage(self):
        """Covered/reached landmarks, then the tensors that ``observe`` and ``info`` hand out."""
        # the observed state, in the observation dtype: [pos, quat, vel, angvel, throttle]
        if self._everyone:
            pos = self._pos
            st = np.concatenate([self._q3, self._v3, self.throttle], axis=-1, dtype=self._np_dtype, casting="same_kind")
        else:
            s = self.state
            pos = s[..., :3]
            st = np.concatenate([s, self.throttle], axis=-1, dtype=self._np_dtype, casting="same_kind")
        # no drone has moved far enough since the last exact test to reach a landmark: covered
        # stays all False and reached as it is (see _check_coverage)
        if self._ref_pos is None or not np.abs(pos - self._ref_pos).max() < self._skin:
            self._check_coverage(pos)
            self._events.pop("covered", None)
        ev = self._events if len(self._events) == len(_EVENT_KEYS) else self._event_tensors()
        # numpy slices wrapped by torch.from_numpy: cheaper than slicing tensors. Every array
        # handed out here is replaced, never written in place, afterwards (reset copies first),
        # so arrays that change only on events keep their tensors (see _event_tensors).
        T = torch.from_numpy if self.device.type == "cpu" else self._tensor
        alive, covered, reached, t = ev["alive"], ev["covered"], ev["reached"], T(self.t)
        self._obs = {"agent_pos": T(st[..., :3]), "agent_vel": T(st[..., 7:10]), "agent_quat": T(st[..., 3:7]),
                     "agent_angvel": T(st[..., 10:13]), "throttle": T(st[..., 13:17]),
                     "landmark_pos": ev["landmark_pos"], "obstacle_pos": self._no_obstacles, "alive": alive,
                     "covered": covered, "reached": reached, "t": t}
        self._info = {"covered": covered, "reached": reached, "collisions": ev["collisions"],
                      "agent_collisions": ev["agent_collisions"], "alive": alive,
                      "done": ev["not_done"] if self._t_max < self.horizon else T(self.t >= self.horizon), "t": t}

    def _check_coverage(self, pos: np.ndarray):
        """The exact test: ``covered``, ``reached``, and the skin that lets later steps skip it.

        A landmark is covered when an alive drone's squared centre distance is at most
        ``reach_distance²``. With ``gap`` the smallest ``distance − reach_distance`` over
        alive drones and landmarks, the skin is ``gap / √3`` less 1 µm (far above float64's
        rounding here): while no drone has moved by the skin or more along any axis since
        this test, every distance has shrunk by less than ``gap − 1 µm``, so none is within
        reach and this test would find nothing covered; ``_update_coverage`` skips it then.
        """
        diff = pos[:, :, None] - self.landmark_pos[:, None]                        # (B, N, L, 3)
        d2 = np.einsum("bnlk,bnlk->bnl", diff, diff)
        if not self._everyone:
            d2 = np.where(self.alive[..., None], d2, np.inf)
        self.covered = (d2 <= self.reach_distance ** 2).any(axis=1)
        self.reached = self.reached | self.covered
        gap = np.sqrt(d2.min()) - self.reach_distance
        if gap > 0 and np.isfinite(gap):
            self._ref_pos, self._skin = pos.copy(), gap / np.sqrt(3) - 1e-6
        else:
            self._ref_pos = None

    def _event_tensors(self) -> dict[str, torch.Tensor]:
        """Tensors of the arrays that change only on events, made again for those dropped from ``_events``.

        ``reset`` clears ``_events``; ``step`` drops ``alive`` when drones leave and
        ``collisions`` (standing for both counts) when it replaces the counts, the exact
        coverage test ``covered`` (standing for ``covered`` and ``reached``)."""
        ev, f32 = self._events, self.dtype == torch.float32
        if "alive" not in ev:
            ev["alive"] = self._tensor(self.alive)
        if "landmark_pos" not in ev:
            ev["landmark_pos"] = self._tensor(self.landmark_pos.astype(np.float32) if f32 else self.landmark_pos)
        if "collisions" not in ev:
            ev["collisions"] = self._tensor(self.collisions)
            ev["agent_collisions"] = self._tensor(self.agent_collisions)
        if "covered" not in ev:  # standing for covered and reached
            ev["covered"], ev["reached"] = self._tensor(self.covered), self._tensor(self.reached)
        if "not_done" not in ev:
            ev["not_done"] = self._tensor(np.zeros(self.num_envs, bool))
        return ev

    def get_rng_state(self) -> torch.Tensor:
        """State of the world's own numpy generator (spawns, team changes) as a uint8 tensor (its JSON),
        for exact resumes; checkpoints hold it as a plain tensor."""
        text = json.dumps(self._rng.bit_generator.state)
        return torch.tensor(list(text.encode()), dtype=torch.uint8)

    def set_rng_state(self, state: torch.Tensor) -> None:
        """Restore a state from :meth:`get_rng_state`."""
        try:
            self._rng.bit_generator.state = json.loads(bytes(state.tolist()).decode())
        except (ValueError, TypeError, KeyError) as e:
            raise ValueError(f"set_rng_state: expected a state from DroneWorld.get_rng_state ({e})") from None

    def get_data(self, env: int = 0) -> mujoco.MjData:
        """A new ``MjData`` of ``self.model`` holding episode ``env``'s physics state (run
        ``mj_forward`` on it for the derived quantities); stepping it leaves the world alone."""
        if not 0 <= env < self.num_envs:
            raise ValueError(f"env: expected an index in [0, {self.num_envs}), got {env}")
        if self._data is None:
            return self.batch.get_data(int(env))
        data = mujoco.MjData(self.model)
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self._data, state, spec)
        mujoco.mj_setState(self.model, data, state, spec)
        return data

    def _tensor(self, a: np.ndarray) -> torch.Tensor:
        t = torch.from_numpy(a)
        return t if self.device.type == "cpu" else t.to(self.device)

    # ------------------------------------------------------------- observing
    @property
    def done(self) -> torch.Tensor:
        return self._info["done"]

    def observe(self) -> dict[str, torch.Tensor]:
        """The observation dict (see the module docstring), a new dict; its tensors are never
        written in place afterwards (those of event-driven arrays are shared between steps)."""
        return dict(self._obs)

    def info(self) -> dict[str, torch.Tensor]:
        return dict(self._info)
