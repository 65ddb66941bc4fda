"""One MASP training iteration: collect an episode in every world, then PPO on both levels.

:class:`MASPTrainer` owns the world, the four networks (:class:`~masp_lite.nets.masp.MASPNets`),
two Adam optimizers (one per level), two :class:`~masp_lite.algos.mappo.ValueNorm` and one
``torch.Generator`` that draws every random number of training (action samples, group
orders, minibatch orders); the world draws spawns from its own generator. Saving and
restoring :meth:`state_dict` therefore restores training exactly.

Per environment step ``t`` of a rollout (all worlds and agents at once, under
``torch.inference_mode``):

1. every ``global_step`` steps the Goal Matcher samples a goal per agent — distinct goals,
   drawn agent by agent in a random order (stored with the picks,
   :mod:`masp_lite.nets.goal_draw`); its reward ``R_GM``
   (eq. 1) is computed at once against the Hungarian assignment;
2. the executor samples an action per agent from its goal and a fresh random group order,
   and the world steps; its inputs (pair features, the groups, goal and obstacle features,
   :class:`~masp_lite.nets.masp.ExecutorInputs`) are stored with the step under their names, so
   the update sees the same groups and does not recompute them every epoch;
3. ``R_CAE`` (eq. 5) is computed after the step.

A rollout is one full episode (horizon steps), so both levels bootstrap from 0 at the
end; the critics see the time left. GAE runs per level on its own time axis (global
steps for the Goal Matcher) and per agent stops at the agent's end, a crash or leaving the
team (:func:`terminal_not_done`), then :func:`~masp_lite.algos.mappo.ppo_update` trains each
level (only the Goal Matcher when ``train_executor`` is off: a fine-tuning stage that
leaves the executor, its critic and its value normalisation untouched).

The ablations and the RL baselines are settings of the same trainer
(:class:`~masp_lite.config.NetConfig`), their parts beside this path: their goals come from a
source of :mod:`masp_lite.algos.goal_sources` (:attr:`MASPTrainer.goal_source`, chosen once), their
networks from :mod:`masp_lite.nets.variants`, the goal-free ones' reward is
:func:`~masp_lite.algos.goal_sources.coverage_reward`; an ``mlp``
variant is built for the scenario's team size. The drone trainer
(:mod:`masp_lite.algos.drone_trainer`) overrides the action step and R_CAE. A research question
changes one part the same way, in a subclass passed to :func:`masp_lite.training.train`
(``trainer_type``): the goal draw (:attr:`MASPTrainer.draw_goals`), the reward
(:meth:`MASPTrainer.executor_reward`) or the networks (:attr:`MASPTrainer.nets_class`).
"""
from __future__ import annotations

import dataclasses

import torch

from ..config import TrainConfig
from ..envs import make
from ..nets.goal_draw import conditional_logits, sequential_sample
from ..nets.masp import MASPNets
from .mappo import UPDATE_STATS, RolloutStorage, ValueNorm, gae, ppo_update, sample
from .rewards import executor_reward, goal_matcher_reward

__all__ = ["MASPTrainer", "sample", "OBS_KEYS", "terminal_not_done"]

OBS_KEYS = ("agent_pos", "agent_vel", "landmark_pos", "obstacle_pos", "alive", "covered", "reached", "t")


def terminal_not_done(alive: torch.Tensor) -> torch.Tensor:
    """``not_done`` (T, B, N) for :func:`~masp_lite.algos.mappo.gae` from ``alive`` (T, B, N), each agent's
    mask at the start of every stored step: 0 where the agent is gone at the next step.

    An agent ends (``term``) when it crashes (drones) or leaves the team (varying teams); its step
    into that end bootstraps nothing, ``delta_t = r_t + gamma (1 - term_{t+1}) V_{t+1} - V_t``, and no
    advantage flows back across it, ``A_t = delta_t + gamma lambda (1 - done_{t+1}) A_{t+1}`` (TorchRL's
    ``generalized_advantage_estimate`` with ``terminated = done``). Within a rollout an agent's end is
    always terminal: the only cut by the horizon is the rollout's last step, which bootstraps 0 (the
    critics see the time left), so its entry here is 1 and unused. The steps after an agent's end are
    masked out of the losses, the advantage statistics and the value normalisation (``mask``). Fixed
    teams are alive throughout: all ones, and training is exactly what it was without it.
    """
    return torch.cat([alive[1:], torch.ones_like(alive[:1])]).to(torch.float32)


class MASPTrainer:
    """MASP on one scenario: ``iteration()`` = one rollout + one update of both levels."""

    distribution = None  # categorical executor actions (the drone trainer's are Gaussian)
    nets_class = MASPNets  # the drone trainer's: DroneNets
    obs_keys = OBS_KEYS  # what a stored step keeps of the observation
    draw_goals = staticmethod(sequential_sample)  # the training draw of distinct goals: (goals, logp, rank)

    def __init__(self, scenario: str, cfg: TrainConfig, seed: int = 0, overrides: dict | None = None):
        self.cfg, self.seed = cfg, int(seed)
        # drone worlds: MuJoCo steps them on as many threads as torch computes on
        self.world = make(scenario, num_envs=cfg.run.num_envs, seed=self.seed, threads=torch.get_num_threads(),
                          **(overrides or {}))
        sc = self.world.scenario
        if sc.kind != cfg.net.world:
            hint = "; drones need --set action=throttle (or velocity)" if sc.kind == "drone" else ""
            raise ValueError(f"masp training: the networks (action {cfg.net.action!r}) are for {cfg.net.world} worlds, "
                             f"the scenario {sc.name!r} is a {sc.kind} world{hint}")
        self.scale, self.horizon, self.reach = sc.world_size / 2, sc.horizon, sc.reach_distance
        if cfg.net.fixed_size:  # an mlp variant: built for this team size
            if cfg.net.team_size not in (0, self.world.num_agents):
                raise ValueError(f"team_size: the mlp variant is set to {cfg.net.team_size} agents, the scenario "
                                 f"{sc.name!r} has {self.world.num_agents}")
            cfg = self.cfg = dataclasses.replace(cfg, net=dataclasses.replace(cfg.net,
                                                                              team_size=self.world.num_agents))
        from .goal_sources import goal_source  # an ablation's or a baseline's goals, beside the paper's path
        self.goal_source = goal_source(cfg.net.goal_matcher)  # None: the Goal Matcher's
        self.gm_trained = self.goal_source is None  # a Goal Matcher to train
        torch.manual_seed(self.seed)  # network initialisation
        self.nets = self.nets_class(cfg.net)
        n = self.nets
        self.gm_opt = torch.optim.Adam([*n.gm.parameters(), *n.gm_critic.parameters()], lr=cfg.ppo.lr, eps=1e-5,
                                       foreach=True)
        self.cae_opt = torch.optim.Adam([*n.cae.parameters(), *n.cae_critic.parameters()], lr=cfg.ppo.lr, eps=1e-5,
                                       foreach=True)
        self.gm_norm, self.cae_norm = ValueNorm(), ValueNorm()
        self.generator = torch.Generator().manual_seed(self.seed + 10_007)
        self.iterations = 0
        self.env_steps = 0
        self.last_row: dict | None = None  # what the last iteration() returned (the live progress shows it)

    # ------------------------------------------------------------------ rollout
    @torch.inference_mode()
    def collect(self):
        """One episode in every world; returns (gm data, cae data, episode stats)."""
        w, n, g, T = self.world, self.nets, self.generator, self.horizon
        obs = w.reset()
        gm, cae = RolloutStorage(), RolloutStorage()
        goals = None
        seen = {k: [obs[k]] for k in ("covered", "reached", "alive")}  # what the metrics read, step by step
        col = []
        B, N = w.num_envs, w.num_agents
        for t in range(T):
            snap = {k: obs[k].clone() for k in self.obs_keys}
            goals = self.goal_step(t, obs, goals, snap, gm)              # 1. the Goal Matcher, every global step
            perm = torch.rand(B, N, generator=g).argsort(-1)            # 2. a fresh random group division
            inputs = n.cae_inputs(obs, goals, perm)
            out, v = n.cae_forward(inputs, obs, T)
            actions, logp, command = self.act(out, obs)                  # the world kind's action step
            alive = obs["alive"].clone()
            obs, info = w.step(command)
            r = self.executor_reward(obs, goals, info, alive, t)         # 3. R_CAE after the step
            cae.add(**snap, **{k: x for k, x in inputs._asdict().items() if k not in snap},  # alive: the snap's
                    actions=actions, logp=logp, values=v, rewards=r, mask=alive)
            for k, history in seen.items():
                history.append(info[k])
            col.append(info["collisions"])
        self.env_steps += T * B
        stats = self.measure(seen, col)
        cfg = self.cfg
        gm_data = self._advantages(gm.stacked(), self.gm_norm, cfg.ppo.gm_gamma) if self.gm_trained else None
        return gm_data, \
            self._advantages(cae.stacked(), self.cae_norm, cfg.ppo.gamma, update=cfg.run.train_executor), stats

    def measure(self, seen: dict, collisions: list) -> dict[str, float]:
        """SR, Steps and CR (means) of a rollout's episodes from what every step ``seen`` (``covered``,
        ``reached``, ``alive`` at reset and after each step) and their ``collisions``: the metrics of
        :mod:`masp_lite.evaluation.metrics`, the one definition ``evaluate`` measures with (a shrinking
        team's SR counts the landmarks ever reached). Imported at the first rollout, as the chunked kernels
        are at the first update: importing the trainer loads no measuring code."""
        from ..evaluation.metrics import EpisodeLog, collision_rate, steps, success_rate
        log = EpisodeLog(*(torch.stack(seen[k], 1) for k in ("covered", "reached")),
                         torch.stack(collisions, 1).long(), torch.stack(seen["alive"], 1),
                         varying=self.world.scenario.varying, horizon=self.horizon)
        return {"sr": float(success_rate(log).mean()), "steps": float(steps(log).mean()),
                "cr": float(collision_rate(log).mean())}

    def goal_step(self, t: int, obs: dict, goals, snap: dict, storage: RolloutStorage):
        """The goals (B, N) for step ``t``: every ``global_step`` steps the Goal Matcher samples distinct
        goals, and the decision is stored with its R_GM. Without a Goal Matcher to train, the goals are
        :attr:`goal_source`'s (an ablation's or a baseline's, :mod:`masp_lite.algos.goal_sources`)."""
        if self.goal_source is not None:
            return self.goal_source.train(t, obs, goals, self.generator, self.cfg.net.global_step,
                                          self.world.scenario.varying)
        if t % self.cfg.net.global_step:
            return goals
        goal_mask = ~obs["reached"] if self.world.scenario.varying else None  # reached ones count for SR already
        logits, v = self.nets.gm_forward(obs, self.scale, self.horizon)
        goals, logp, rank = self.draw_goals(logits, obs["alive"], self.generator)
        r = goal_matcher_reward(obs["agent_pos"], obs["landmark_pos"], goals, obs["alive"], goal_mask,
                                power=2.0 if self.cfg.reward.gm_reference == "squared" else 1.0)
        storage.add(**snap, actions=goals, rank=rank, logp=logp, values=v, rewards=r, mask=obs["alive"].clone())
        return goals

    def act(self, out, obs: dict):
        """The action step: ``(actions stored, their log-probabilities, what the world steps with)``.

        Particles: one of MPE's 5 actions per agent, sampled from the executor's logits (dropped
        agents send 0). The drone trainer samples its Gaussian and turns it into motor commands."""
        actions, logp = sample(out, self.generator)
        return actions, logp, torch.where(obs["alive"], actions, torch.zeros_like(actions))

    def executor_reward(self, obs: dict, goals, info: dict, alive, t: int) -> torch.Tensor:
        """R_CAE (eq. 5) of step ``t``, from the observation after it; the goal-free baselines' coverage reward."""
        rc, world_size = self.cfg.reward, self.world.scenario.world_size
        if goals is None:  # no goals: the goal-free baselines' reward, beside the paper's path
            from .goal_sources import coverage_reward
            return coverage_reward(obs["agent_pos"], obs["landmark_pos"], info["agent_collisions"], alive,
                                   self.reach, world_size, rc.bonus_coef, rc.distance_coef, rc.collision_coef)
        goal_pos = torch.gather(obs["landmark_pos"], 1, goals.unsqueeze(-1).expand_as(obs["agent_pos"]))
        return executor_reward(obs["agent_pos"], goal_pos, info["agent_collisions"], alive, self.reach, world_size,
                               rc.bonus_coef, rc.distance_coef, rc.collision_coef)

    def _advantages(self, data, norm: ValueNorm, gamma: float, update: bool = True):
        """GAE per agent that stops at the agent's end: :func:`terminal_not_done` of the stored ``mask``."""
        values = norm.denormalize(data["values"])
        adv, ret = gae(data["rewards"], values, torch.zeros_like(values[0]), gamma, self.cfg.ppo.gae_lambda,
                       not_done=terminal_not_done(data["mask"]))
        data["advantages"], data["returns"] = adv, ret
        if update:  # a frozen level keeps its value normalisation too
            norm.update(ret, data["mask"])
        data["reward_mean"] = data["rewards"]
        return data

    # ------------------------------------------------------------------ update
    def gm_evaluate(self, mb):
        """A minibatch's Goal Matcher logits (restricted as drawn) and values: what its PPO update recomputes."""
        obs = {k: mb[k] for k in self.obs_keys}
        logits, values = self.nets.gm_forward(obs, self.scale, self.horizon)
        return conditional_logits(logits, mb["actions"], mb["rank"], obs["alive"]), values

    def cae_evaluate(self, mb):
        """A minibatch's executor output and values from the stored inputs: what its PPO update recomputes."""
        obs = {k: mb[k] for k in self.obs_keys}
        inputs = self.nets.inputs_type(**{k: mb[k] for k in self.nets.inputs_type._fields})
        return self.nets.cae_forward(inputs, obs, self.horizon)

    def iteration(self) -> dict[str, float]:
        """Collect, update both levels; returns the row logged to ``progress.csv``."""
        gm_data, cae_data, stats = self.collect()
        r_cae = float(cae_data.pop("reward_mean")[cae_data["mask"]].mean())
        n, cfg = self.nets, self.cfg
        nothing = dict.fromkeys(UPDATE_STATS, float("nan"))
        if gm_data is None:  # random or Hungarian goals: no Goal Matcher to train
            r_gm, s_gm = float("nan"), dict(nothing)
        else:
            r_gm = float(gm_data.pop("reward_mean")[gm_data["mask"]].mean())
            s_gm = ppo_update(gm_data, self.gm_evaluate, n.gm, n.gm_critic, self.gm_opt, cfg.ppo, self.gm_norm,
                              self.generator, epochs=cfg.ppo.gm_ppo_epochs)
        if cfg.run.train_executor:
            s_cae = ppo_update(cae_data, self.cae_evaluate, n.cae, n.cae_critic, self.cae_opt, cfg.ppo, self.cae_norm,
                               self.generator, distribution=self.distribution)
        else:  # executor frozen (Goal Matcher fine-tuning): nothing to report
            s_cae = dict(nothing)
        self.iterations += 1
        row = {"iteration": self.iterations, "env_steps": self.env_steps, **{f"train_{k}": v for k, v in stats.items()},
               "gm_reward": r_gm, "cae_reward": r_cae}
        row.update({f"gm_{k}": v for k, v in s_gm.items()})
        row.update({f"cae_{k}": v for k, v in s_cae.items()})
        self.last_row = row
        return row

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        """Everything needed to continue exactly: weights, optimizers, value norms, all RNG states."""
        return {"nets": self.nets.state_dict(), "gm_opt": self.gm_opt.state_dict(),
                "cae_opt": self.cae_opt.state_dict(), "gm_norm": self.gm_norm.state_dict(),
                "cae_norm": self.cae_norm.state_dict(), "generator": self.generator.get_state(),
                "world_rng": self.world.get_rng_state(), "iterations": self.iterations,
                "env_steps": self.env_steps, "config": self.cfg.flat(), "seed": self.seed}

    def load_state_dict(self, state: dict) -> None:
        self.nets.load_state_dict(state["nets"])
        self.gm_opt.load_state_dict(state["gm_opt"])
        self.cae_opt.load_state_dict(state["cae_opt"])
        self.gm_norm.load_state_dict(state["gm_norm"])
        self.cae_norm.load_state_dict(state["cae_norm"])
        self.generator.set_state(state["generator"])
        self.world.set_rng_state(state["world_rng"])
        self.iterations, self.env_steps = int(state["iterations"]), int(state["env_steps"])
