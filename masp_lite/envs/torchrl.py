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

Resets: ``reset()`` starts every world; a ``"_reset"`` mask (B, 1) starts only those worlds
(:meth:`ParticleWorld.reset` with ``env_ids``), the others keep their state. ``set_seed(s)``
seeds the world's generator, so ``set_seed(s); reset()`` starts the same episodes as
``ParticleWorld(scenario, num_envs, seed=s)``; ``seed=`` in the constructor does the same.
"""
from __future__ import annotations

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
        # the agents j != i of every agent i in index order, flattened (the "other agents" blocks' order)
        idx = torch.arange(N, device=dev)
        self._others = idx.expand(N, N)[idx[:, None] != idx[None, :]]
        ends = torch.tensor([2, 2, 2 * N, 2 * (N - 1), 2 * (N - 1), N - 1, 2 * K]).cumsum(0).tolist()
        self._blocks = list(zip([0, *ends[:-1]], ends))  # the observation's blocks, in order
        # per-world metric counters: collision events so far, first step with SR 1 (-1: not yet)
        self._collided = torch.zeros(B, dtype=torch.long, device=dev)
        self._first = torch.full((B,), -1, dtype=torch.long, device=dev)
        self._acting = world.alive
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
        return self._output(self._observation()[0], solved)

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
        obs, dist2 = self._observation()
        reward = self._reward(dist2, info["agent_collisions"]) * self._acting  # 0 for agents already gone
        self._acting = w.alive
        return self._output(obs, solved, reward.to(torch.float32).unsqueeze(-1))

    # ------------------------------------------------------------- helpers
    def _solved(self) -> torch.Tensor:
        """(B,) SR-so-far is 1 (fixed teams: every landmark covered now; varying: every one reached)."""
        w = self.world
        return (w.reached if self.scenario.varying else w.covered).all(dim=-1)

    def _observation(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The PettingZoo face's per-agent observation for every world, (B, N, 7N - 1 + 2K) float32,
        and the squared agent-landmark distances (B, N agents, N landmarks) the reward needs.

        This runs every step on about as many numbers as the physics touches, so each block is
        written into its slice of one fresh tensor, one coordinate at a time: broadcasting over
        a length-N axis is several times faster than over the (x, y) pairs."""
        w, N = self.world, self.num_agents
        pos, vel, alive = w.agent_pos, w.agent_vel, w.alive
        B, K = pos.shape[0], w.num_obstacles
        out = torch.empty(B, N, self.obs_dim, dtype=pos.dtype, device=pos.device)
        own_vel, own_pos, lms, rel_pos, rel_vel, flags, obst = (out[..., a:b] for a, b in self._blocks)
        own_vel.copy_(vel)
        own_pos.copy_(pos)

        def others(x):  # (B, N) -> (B, N, N - 1): x_j of the agents j != i, for every agent i
            return x.index_select(1, self._others).view(B, N, N - 1)

        left = None if bool(alive.all()) else ~others(alive)
        dist2 = None
        for c in range(2):  # x, then y: block[b, i, j, c] = other_j[c] - own_i[c]
            own = pos[..., c].unsqueeze(2)
            to_lm = w.landmark_pos[..., c].unsqueeze(1) - own                    # contiguous (B, N, N)
            lms.view(B, N, N, 2)[..., c].copy_(to_lm)
            dist2 = to_lm * to_lm if dist2 is None else dist2.addcmul_(to_lm, to_lm)
            torch.sub(w.obstacle_pos[..., c].unsqueeze(1), own, out=obst.view(B, N, K, 2)[..., c])
            for block, x in ((rel_pos, pos), (rel_vel, vel)):
                xc = x[..., c]
                dst = torch.sub(others(xc), xc.unsqueeze(2), out=block.view(B, N, N - 1, 2)[..., c])
                if left is not None:  # a dropped agent's slots are zero
                    dst.masked_fill_(left, 0.0)
        flags.fill_(1.0) if left is None else flags.copy_(~left)
        return out.to(torch.float32), dist2

    def _reward(self, dist2: torch.Tensor, contacts: torch.Tensor) -> torch.Tensor:
        """(B, N): simple_spread's reward of every agent (module docstring), from the squared
        agent-landmark distances of :meth:`_observation` (the world's precision)."""
        alive = self.world.alive
        if not bool(alive.all()):  # dropped agents cover nothing
            dist2 = torch.where(alive.unsqueeze(-1), dist2, torch.inf)
        nearest = dist2.amin(dim=1).sqrt()
        team = -nearest.sum(dim=-1, keepdim=True)
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
