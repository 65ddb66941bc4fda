"""Policy gradients from scratch, on one particle agent (chapter 04b's pieces).

MASP's two levels are trained by MAPPO (:mod:`masp_lite.algos.mappo`, chapter 05). This module
is the smallest learning problem on the same world, to see each idea of policy-gradient
reinforcement learning work before MASP uses it:

* the world: ``mpe-5``'s physics with **one** agent, one landmark and no obstacle
  (:func:`single_agent_world`); the agent pushes in one of MPE's five directions each step;
* the reward: minus the distance to the landmark after each step (closer is better);
* the policy: a linear layer from five features (the landmark relative to the agent, the
  agent's velocity, a constant) to the five action logits (:class:`LinearPolicy`);
* :func:`discounted_returns` — ``G_t = r_t + gamma G_{t+1}``, backwards in time;
* :func:`reinforce_loss` — ``-mean(log pi(a_t | o_t) A_t)`` with the advantages scaled by
  their spread over the batch: its gradient is the policy gradient (REINFORCE);
* :func:`train_policy_gradient` — REINFORCE without a baseline, with the batch mean as a
  baseline, with a learned critic and GAE (``mappo.gae``), or with PPO's clipped objective
  (``mappo.clipped_surrogate``) over several epochs of the same batch.

Everything is batch-first: ``B`` episodes side by side, time on axis 0 of the rollouts.
"""
from __future__ import annotations

import torch
from torch import nn

from .algos import mappo
from .envs import make

__all__ = ["single_agent_world", "features", "LinearPolicy", "discounted_returns", "reinforce_loss",
           "collect", "train_policy_gradient", "METHODS"]

#: The variants :func:`train_policy_gradient` runs.
METHODS = ("reinforce", "baseline", "critic", "ppo")


def single_agent_world(num_envs: int = 64, seed: int = 0):
    """``mpe-5``'s physics and map with one agent, one landmark and no obstacle."""
    return make("mpe-5", num_envs=num_envs, seed=seed, num_agents=1, num_obstacles=0)


def features(obs: dict) -> torch.Tensor:
    """(B, 5): the landmark relative to the agent (2), the agent's velocity (2), a constant 1."""
    rel = obs["landmark_pos"][:, 0] - obs["agent_pos"][:, 0]
    vel = obs["agent_vel"][:, 0]
    return torch.cat([rel, vel, torch.ones_like(rel[:, :1])], dim=-1)


class LinearPolicy(nn.Module):
    """Five features -> five action logits; the critic is a second linear layer -> one value."""

    def __init__(self):
        super().__init__()
        self.actor = nn.Linear(5, 5)
        self.critic = nn.Linear(5, 1)
        nn.init.zeros_(self.actor.weight)                 # a uniform policy to start from
        nn.init.zeros_(self.actor.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.actor(x)

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)


def discounted_returns(rewards: torch.Tensor, gamma: float, not_done: torch.Tensor | None = None) -> torch.Tensor:
    """``G_t = r_t + gamma * not_done_t * G_{t+1}`` over time axis 0 (``G`` after the last step is 0).

    ``not_done`` (T, ...) is 0 where step ``t`` ended an episode, so no reward of the next
    episode flows back into this one. Example: rewards 1, 1, 1 with ``gamma = 0.5`` ->
    1.75, 1.5, 1."""
    out = torch.zeros_like(rewards)
    running = torch.zeros_like(rewards[0])
    nd = torch.ones_like(rewards) if not_done is None else not_done.to(rewards.dtype)
    for t in reversed(range(rewards.shape[0])):
        running = rewards[t] + gamma * nd[t] * running
        out[t] = running
    return out


def reinforce_loss(logits: torch.Tensor, actions: torch.Tensor, advantages: torch.Tensor) -> torch.Tensor:
    """``-mean(log pi(a | o) * A)``, with ``A`` divided by its standard deviation over the batch.

    ``logits`` (..., A), ``actions`` and ``advantages`` (...). The advantages are constants
    (no gradient flows through them). Dividing by their spread keeps the step size the same
    whatever the scale of the rewards; it does not centre them: subtracting a baseline is the
    caller's choice (:func:`train_policy_gradient`), so that its effect can be seen."""
    adv = advantages.detach()
    adv = adv / (adv.std() + 1e-8)
    logp = torch.log_softmax(logits, dim=-1).gather(-1, actions.unsqueeze(-1)).squeeze(-1)
    return -(logp * adv).mean()


def collect(world, policy: LinearPolicy, generator: torch.Generator, seed: int | None = None) -> dict:
    """One episode in every world, actions sampled from ``policy``: features (T, B, 5), actions,
    their log-probabilities, rewards (T, B), the last features and whether the landmark is covered."""
    obs = world.reset(seed=seed)
    feats, actions, logps, rewards = [], [], [], []
    with torch.no_grad():
        while not bool(world.done.all()):
            x = features(obs)
            a, logp = mappo.sample(policy(x), generator)
            obs, info = world.step(a.unsqueeze(-1))
            feats.append(x)
            actions.append(a)
            logps.append(logp)
            rewards.append(-features(obs)[:, :2].norm(dim=-1))
    return {"features": torch.stack(feats), "actions": torch.stack(actions), "logp": torch.stack(logps),
            "rewards": torch.stack(rewards), "last": features(obs), "covered": info["covered"][:, 0].float()}


def train_policy_gradient(method: str = "baseline", iterations: int = 100, num_envs: int = 64, seed: int = 0,
                          lr: float = 0.05, gamma: float = 0.95, lam: float = 0.9, clip: float = 0.2,
                          epochs: int = 4) -> dict:
    """Train a :class:`LinearPolicy` on :func:`single_agent_world`; returns ``{"policy", "return", "sr"}``.

    ``method``: ``"reinforce"`` (advantage = the return), ``"baseline"`` (the return minus the
    batch's mean return at that step), ``"critic"`` (GAE on a learned value, which is fitted
    to the returns) or ``"ppo"`` (the critic's advantages, ``epochs`` passes of the clipped
    surrogate over each batch). ``"return"`` and ``"sr"`` are per-iteration lists: the mean
    undiscounted return of the batch and the share of episodes ending on the landmark."""
    if method not in METHODS:
        raise ValueError(f"train_policy_gradient: expected method in {METHODS}, got {method!r}")
    torch.manual_seed(seed)
    policy = LinearPolicy()
    opt = torch.optim.Adam(policy.parameters(), lr=lr)
    world = single_agent_world(num_envs, seed=seed)
    gen = torch.Generator().manual_seed(seed)
    history = {"policy": policy, "return": [], "sr": []}
    for _ in range(iterations):
        batch = collect(world, policy, gen)
        x, actions, rewards = batch["features"], batch["actions"], batch["rewards"]
        returns = discounted_returns(rewards, gamma)
        if method == "reinforce":
            adv = returns
        elif method == "baseline":
            adv = returns - returns.mean(dim=1, keepdim=True)
        else:
            with torch.no_grad():
                values = policy.value(x)
                adv, returns = mappo.gae(rewards, values, torch.zeros_like(values[0]), gamma, lam)
        for _ in range(epochs if method == "ppo" else 1):
            logits = policy(x)
            if method == "ppo":
                logp = torch.log_softmax(logits, -1).gather(-1, actions.unsqueeze(-1)).squeeze(-1)
                norm = (adv - adv.mean()) / (adv.std() + 1e-8)
                loss = mappo.clipped_surrogate(logp, batch["logp"], norm, clip)
            else:
                loss = reinforce_loss(logits, actions, adv)
            if method in ("critic", "ppo"):
                loss = loss + 0.5 * (policy.value(x) - returns).pow(2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
        history["return"].append(float(rewards.sum(0).mean()))
        history["sr"].append(float(batch["covered"].mean()))
    return history
