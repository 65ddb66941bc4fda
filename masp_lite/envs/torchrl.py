"""TorchRL face of the batched particle world: ``num_envs`` episodes as one ``torchrl.envs.EnvBase``.

``ParticleTorchRLEnv(scenario, num_envs=1, device="cpu", seed=None, **overrides)`` wraps a
:class:`~masp_lite.envs.particle.ParticleWorld` (physics, spawns, team change are the
world's) in TorchRL's multi-agent layout, the one its ``VmasEnv`` uses, so TorchRL's
collectors and losses — and BenchMARL's algorithms — run on the paper's presets as they
run on VMAS. Needs the optional extra: ``pip install masp-lite[torchrl]``. Particle
scenarios only (``mpe-*``); the drone world's float motor commands and MuJoCo steps are
not wrapped here.

Batch size ``(num_envs,)``; ``B`` worlds, ``N`` agents (= landmarks), ``K`` obstacles:

=================================  ============  ==============================================
key                                shape         meaning
=================================  ============  ==============================================
``("agents", "action")``           (B, N) int64  ``Categorical(5)``: 0 no-op, 1 −x, 2 +x, 3 −y, 4 +y
``("agents", "observation")``      (B, N, D)     float32, ``D = 7N − 1 + 2K``: the PettingZoo
                                                 face's observation (:mod:`.pettingzoo.particle`)
``("agents", "mask")``             (B, N) bool   the agent is in the team (the world's ``alive``)
``("agents", "reward")``           (B, N, 1)     float32, the PettingZoo face's reward (below)
``"done"`` / ``"truncated"``       (B, 1) bool   the episode reached its horizon
``"terminated"``                   (B, 1) bool   always False: the task has no early end
``("episode", "success_rate")``    (B,) float64  SR of the episode so far (below)
``("episode", "steps")``           (B,) float64  Steps so far
``("episode", "collision_rate")``  (B,) float64  CR so far
``("episode", "solved")``          (B,) bool     SR 1 was reached at some step
=================================  ============  ==============================================

**Reward** (per agent, as :class:`~masp_lite.envs.pettingzoo.particle.ParticleParallelEnv`
computes it): mpe2's ``simple_spread`` reward with ``local_ratio = 0.5``, obstacles counted
as contacts, ``r_i = 0.5 · (−Σ_l min_{alive j} |p_j − l|) + 0.5 · (−contacts_i)``, where
``contacts_i`` is the world's ``agent_collisions`` after the step. The distances are taken
in the world's float32 (the PettingZoo face takes them in float64), so the two agree to
float32 rounding. MASP itself trains on its own rewards (:mod:`masp_lite.algos.rewards`).

**Shrinking teams** (``mpe-20to10``, …): the world drops agents after ``change_step``. A
dropped agent stays in every tensor so shapes never change: its ``mask`` turns False at
the step it leaves; the world ignores its actions from then on (it no longer moves or
collides); its reward is the step's reward at the step it leaves (the PettingZoo face
gives it then, with ``terminated``) and 0 after; its observation row is still filled
(frozen own position, no other agent sees it). Mask dropped agents out of losses with
``("agents", "mask")``. The root done keys say when the whole episode ends (every agent
at once, at the horizon), as in ``VmasEnv``.

**Metrics** (the paper's, as :mod:`masp_lite.evaluation.metrics` defines them), per world,
updated every step and final when ``"done"`` is True; log them there (:func:`finished_episodes`):

* ``success_rate``: fraction of landmarks covered now (fixed teams) or ever reached
  (varying teams) — at the horizon, ``metrics.success_rate``;
* ``steps``: the first step count ``t`` (0 = at reset) at which that fraction was 1, else the
  horizon — ``metrics.steps``; ``solved`` is ``metrics.reached_target``;
* ``collision_rate``: collision events (contact pairs after each step) summed so far, over
  the steps taken so far — at the horizon, ``metrics.collision_rate``.

**Memory**: each step's observation is a new tensor, but it may reuse the memory of an
earlier one that nothing can reach any more (:class:`_Recycler`): an observation that is
held in any way (a TensorDict, a view, a numpy array, its storage) keeps its numbers.

Resets: ``reset()`` starts every world; a ``"_reset"`` mask (B, 1) starts only those worlds
(:meth:`ParticleWorld.reset` with ``env_ids``), the others keep their state. ``set_seed(s)``
seeds the world's generator, so ``set_seed(s); reset()`` starts the same episodes as
``ParticleWorld(scenario, num_envs, seed=s)``; ``seed=`` in the constructor does the same.
"""
from __future__ import annotations

import sys
import weakref

import torch

from .particle import NUM_ACTIONS, ParticleWorld
from .pettingzoo.particle import LOCAL_RATIO
from .scenarios import Scenario

try:
    from tensordict import TensorDict, TensorDictBase
    from torchrl.data import Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase
except ImportError as e:  # the optional extra is missing
    raise ImportError("masp_lite.envs.torchrl needs TorchRL and tensordict: pip install masp-lite[torchrl] "
                      f"({e})") from e

__all__ = ["ParticleTorchRLEnv", "METRICS", "finished_episodes"]

#: The per-world metric keys under ``"episode"``.
METRICS = ("success_rate", "steps", "collision_rate", "solved")


def finished_episodes(td: TensorDictBase) -> dict[str, torch.Tensor]:
    """The metrics of every episode that ended in ``td`` (a rollout or collector batch), 1-D each.

    Reads ``("next", "episode", key)`` where ``("next", "done")`` is True, so each finished
    episode is counted once, at its last step."""
    done = td.get(("next", "done"), None)
    episode = td.get(("next", "episode"), None)
    if done is None or episode is None:
        raise ValueError("finished_episodes: expected a rollout or collector batch with ('next', 'done') and "
                         "('next', 'episode') entries")
    done = done.squeeze(-1)
    return {k: episode.get(k)[done] for k in METRICS}


class ParticleTorchRLEnv(EnvBase):
    """``num_envs`` particle-world episodes as a TorchRL multi-agent env (module docstring: keys, reward)."""

    def __init__(self, scenario: str | Scenario = "mpe-5", num_envs: int = 1,
                 device: str | torch.device = "cpu", seed: int | None = None, **overrides):
        world = ParticleWorld(scenario, num_envs=num_envs, device=device, seed=seed, **overrides)
        super().__init__(device=world.device, batch_size=torch.Size([world.num_envs]))
        self.world, self.scenario = world, world.scenario
        B, N, K = world.num_envs, world.num_agents, world.num_obstacles
        self.num_agents, self.obs_dim = N, 7 * N - 1 + 2 * K
        dev = self.device
        # slot k of agent i's "other agents" blocks holds agent k (k < i) or agent k + 1 (k >= i)
        idx = torch.arange(N, device=dev)
        self._before = idx[:, None] > idx[None, :N - 1]                                  # (N, N - 1)
        self._others = idx[None, :N - 1] + (~self._before).long()                        # (N, N - 1) agent ids
        # per-world metric counters: collision events so far, first step with SR 1 (-1: not yet)
        self._collided = torch.zeros(B, dtype=torch.long, device=dev)
        self._first = torch.full((B,), -1, dtype=torch.long, device=dev)
        self._acting = world.alive
        self._recycler = _Recycler()
        self._agents_shape, self._episode_shape = torch.Size([B, N]), torch.Size([B])
        flag = dict(n=2, dtype=torch.bool, device=dev)
        self.observation_spec = Composite(
            agents=Composite(observation=Unbounded((B, N, self.obs_dim), dtype=torch.float32, device=dev),
                             mask=Categorical(shape=(B, N), **flag), shape=(B, N)),
            episode=Composite(success_rate=Unbounded((B,), dtype=torch.float64, device=dev),
                              steps=Unbounded((B,), dtype=torch.float64, device=dev),
                              collision_rate=Unbounded((B,), dtype=torch.float64, device=dev),
                              solved=Categorical(shape=(B,), **flag), shape=(B,)),
            shape=(B,))
        self.action_spec = Composite(
            agents=Composite(action=Categorical(n=NUM_ACTIONS, shape=(B, N), dtype=torch.long, device=dev),
                             shape=(B, N)), shape=(B,))
        self.reward_spec = Composite(
            agents=Composite(reward=Unbounded((B, N, 1), dtype=torch.float32, device=dev), shape=(B, N)),
            shape=(B,))
        self.done_spec = Composite(done=Categorical(shape=(B, 1), **flag), terminated=Categorical(shape=(B, 1), **flag),
                                   truncated=Categorical(shape=(B, 1), **flag), shape=(B,))
        if seed is not None:
            self._set_seed(seed)  # the first reset() starts the episodes ParticleWorld(seed=seed) starts

    def __repr__(self):
        return f"{type(self).__name__}({self.scenario.name!r}, num_envs={self.world.num_envs}, " \
               f"num_agents={self.num_agents}, device={str(self.device)!r})"

    # ------------------------------------------------------------- TorchRL
    def _set_seed(self, seed: int | None) -> None:
        gen = torch.Generator()
        gen.seed() if seed is None else gen.manual_seed(int(seed))
        self.world.set_rng_state(gen.get_state())

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        w = self.world
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if mask is None or bool(mask.all()):
            w.reset()
            fresh = torch.ones(w.num_envs, dtype=torch.bool, device=self.device)
        else:
            fresh = mask.reshape(w.num_envs).to(self.device)
            w.reset(env_ids=fresh.nonzero().squeeze(-1))
        solved = self._solved()
        self._collided = torch.where(fresh, 0, self._collided)
        self._first = torch.where(fresh, torch.where(solved, 0, -1), self._first)
        self._acting = w.alive
        return self._output(self._observation(), solved)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        w = self.world
        action = tensordict.get(("agents", "action"), None)
        want = (w.num_envs, w.num_agents)
        if action is None or tuple(action.shape) != want:
            got = "nothing" if action is None else f"shape {tuple(action.shape)}"
            raise ValueError(f"step: expected integer action ids at ('agents', 'action') with shape "
                             f"(num_envs, num_agents) = {want} (one id in [0, {NUM_ACTIONS}) per agent, "
                             f"not one-hot), got {got}")
        _, info = w.step(action)
        self._collided = self._collided + info["collisions"]
        solved = self._solved()
        self._first = torch.where((self._first < 0) & solved, w.t, self._first)
        reward = self._reward(info["agent_collisions"]) * self._acting  # 0 for agents already gone
        self._acting = w.alive
        return self._output(self._observation(), solved, reward.to(torch.float32).unsqueeze(-1))

    # ------------------------------------------------------------- helpers
    def _solved(self) -> torch.Tensor:
        """(B,) SR-so-far is 1 (fixed teams: every landmark covered now; varying: every one reached)."""
        w = self.world
        return (w.reached if self.scenario.varying else w.covered).all(dim=-1)

    def _observation(self) -> torch.Tensor:
        """The PettingZoo face's per-agent observation for every world, (B, N, 7N - 1 + 2K) float32.

        This runs every step on about as many numbers as the physics touches, so it is written
        for speed. Each (x, y) pair is one complex number, so every "other minus own" block is
        one broadcast subtraction over a length-N axis (complex subtraction is the componentwise
        float subtraction, so the numbers are the same to the bit). The "other agents" blocks
        skip agent i without a gather: slot k takes agent k before i and agent k + 1 from i on
        (one ``torch.where`` over a precomputed (N, N - 1) mask), then subtracts agent i."""
        w, N = self.world, self.num_agents
        pos, vel, alive = _complex(w.agent_pos), _complex(w.agent_vel), w.alive
        B = pos.shape[0]
        out = self._recycler.empty((B, N, self.obs_dim), torch.float32, pos.device)

        def put(start, block):  # (B, N, M) complex -> the M (x, y) pairs from column `start` on
            out[..., start:start + 2 * block.shape[-1]].view(*block.shape, 2).copy_(torch.view_as_real(block))

        put(0, torch.stack((vel, pos), dim=-1))
        own = pos.unsqueeze(2)
        put(4, _complex(w.landmark_pos).unsqueeze(1) - own)
        left = None if bool(alive.all()) else ~alive[:, self._others]                    # (B, N, N - 1)
        for start, x in ((2 * N + 4, pos), (4 * N + 2, vel)):
            row = x.unsqueeze(1)                                             # slot k: x_k (k < i) or x_(k+1)
            block = torch.where(self._before, row[..., :-1], row[..., 1:]).sub_(x.unsqueeze(2))
            if left is not None:  # a dropped agent's slots are zero
                block.masked_fill_(left, 0)
            put(start, block)
        flags = out[..., 6 * N:7 * N - 1]
        flags.fill_(1.0) if left is None else flags.copy_(~left)
        put(7 * N - 1, _complex(w.obstacle_pos).unsqueeze(1) - own)
        return out

    def _reward(self, contacts: torch.Tensor) -> torch.Tensor:
        """(B, N): simple_spread's reward of every agent (module docstring), the distances in the
        world's precision: x and y apart, so every pass runs over contiguous (B, N, N) tensors."""
        w = self.world
        pos, lms = w.agent_pos.transpose(1, 2).contiguous(), w.landmark_pos.transpose(1, 2).contiguous()  # (B, 2, N)
        dx = lms[:, 0].unsqueeze(1) - pos[:, 0].unsqueeze(2)                           # (B, N agents, N landmarks)
        dy = lms[:, 1].unsqueeze(1) - pos[:, 1].unsqueeze(2)
        dist2 = dx.square_().addcmul_(dy, dy)
        if not bool(w.alive.all()):  # dropped agents cover nothing
            dist2.masked_fill_(~w.alive.unsqueeze(-1), torch.inf)
        team = -dist2.amin(dim=1).sqrt_().sum(dim=-1, keepdim=True)
        return (1 - LOCAL_RATIO) * team - LOCAL_RATIO * contacts

    def _output(self, obs: torch.Tensor, solved: torch.Tensor, reward: torch.Tensor | None = None) -> TensorDictBase:
        """The reset/step output: observation, mask, reward (steps only), metrics, done keys."""
        w, sc = self.world, self.scenario
        agents = {"observation": obs, "mask": w.alive}
        if reward is not None:
            agents["reward"] = reward
        taken = w.t.clamp(min=1).double()
        episode = {"success_rate": (w.reached if sc.varying else w.covered).double().mean(dim=-1),
                   "steps": torch.where(self._first >= 0, self._first, sc.horizon).double(),
                   "collision_rate": self._collided.double() / taken, "solved": self._first >= 0}
        over = w.done.unsqueeze(-1)
        return TensorDict({"agents": TensorDict(agents, batch_size=self._agents_shape, device=self.device),
                           "episode": TensorDict(episode, batch_size=self._episode_shape, device=self.device),
                           "done": over, "terminated": torch.zeros_like(over), "truncated": over.clone()},
                          batch_size=self.batch_size, device=self.device)


def _complex(xy: torch.Tensor) -> torch.Tensor:
    """(..., 2) real -> (...) complex view of the same numbers (a copy only when no view is possible)."""
    if not xy.is_contiguous() or xy.storage_offset() % 2:
        xy = xy.clone(memory_format=torch.contiguous_format)
    return torch.view_as_complex(xy)


class _Recycler:
    """Fresh tensors that reuse the memory of earlier ones nobody can see any more.

    The face's observation is the largest tensor it makes each step (5.2 MB at mpe-50 x 64
    worlds). Fresh memory of that size is often fresh pages from the system, a page fault
    per 4 KiB the first time it is written: in ``bench env``'s loop, 300–460 faults per step
    against none for the native world (about a tenth of its step time), a number that drifts
    with the heap's history. So the face keeps the last ``keep`` tensors it handed out and
    writes a new observation into one of them only when nothing else can reach its memory:
    no Python reference to the tensor (a TensorDict, a list, a numpy array, a view's
    ``_base``), no weak reference, no other C++ reference, no other tensor on its storage, no
    reference to the storage, and not in shared memory (another process may hold it).
    Anything still held keeps its numbers."""

    def __init__(self, keep: int = 4):
        self.keep, self._kept = keep, []

    def empty(self, shape: tuple, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
        for t in self._kept:
            if tuple(t.shape) == shape and t.dtype == dtype and t.device == device and self._unreachable(t):
                return t
        t = torch.empty(shape, dtype=dtype, device=device)
        self._kept = [t, *self._kept[:self.keep - 1]]
        return t

    @staticmethod
    def _unreachable(t: torch.Tensor) -> bool:
        # references: the list, the loop variable, this argument, getrefcount's own argument
        if sys.getrefcount(t) != 4 or t._use_count() != 1 or weakref.getweakrefcount(t) or t.is_shared():
            return False
        storage = t.untyped_storage()  # its one Python object: here, getrefcount's argument, the storage itself
        return sys.getrefcount(storage) == 3 and torch._C._storage_Use_Count(storage._cdata) == 2
