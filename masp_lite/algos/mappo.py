"""MAPPO pieces shared by MASP's two levels: storage, GAE, PPO losses, value normalisation.

MAPPO (Yu et al. 2022) is PPO with parameters shared by the agents and a centralized
critic. MASP trains its Goal Matcher (one transition per global step) and its executor
(one per environment step) with it, together (paper, section "Overview"). This module
holds what both levels use, each piece a small function:

* :func:`gae` — generalized advantage estimation, backwards over time;
* :func:`clipped_surrogate` — PPO's clipped policy loss;
* :func:`value_loss` — clipped Huber value loss on normalised targets;
* :class:`ValueNorm` — running mean/std of the returns (MAPPO's value normalisation);
* :class:`RolloutStorage` — named per-step tensors stacked into (T, B, ...) and cut into
  minibatches of (step, world) rows (a row keeps all agents of a world together, since
  the graph networks need the whole team);
* :func:`sample` — categorical samples (the executor's 5 MPE actions, the Goal Matcher's goals);
* :func:`ppo_update` — epochs x minibatches of the combined loss, with gradient clipping; it
  reports the losses and what CleanRL and Spinning Up log to tell a healthy update from a
  collapsing one (:data:`UPDATE_STATS`: approximate KL, clip fraction, explained variance).

The settings (:class:`masp_lite.config.PPOConfig`) default to MAGE-X's MAPPO settings
(lr 7e-4, clip 0.2, entropy 0.01, gamma 0.99,
lambda 0.95, Huber delta 10, max grad norm 10, value normalisation). Why hand-written:
the MARL libraries' PPO (e.g. ``on-policy``) assume flat per-agent observations; ours are
graphs whose rows must keep a world's agents together.
"""
from __future__ import annotations

import torch
from torch import nn

from ..config import PPOConfig

__all__ = ["gae", "clipped_surrogate", "value_loss", "ValueNorm", "RolloutStorage", "sample", "ppo_update",
           "NonFiniteError", "UPDATE_STATS", "HEALTH", "explained_variance"]

UPDATE_STATS = ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction", "explained_variance")
"""What :func:`ppo_update` reports, in this order: the three loss terms (means over its minibatches), and
PPO's health: ``approx_kl`` — how far the policy moved from the one that collected the rollout, CleanRL's
estimator ``E[(rho - 1) - log rho]`` (>= 0; a few thousandths is a gentle step, well above ``clip / 10``
the clip is doing all the work); ``clip_fraction`` — the share of samples whose ratio left
``[1 - clip, 1 + clip]`` (0.0-0.2 is usual; near 1 the update has run off); both means over the minibatches;
``explained_variance`` — ``1 - Var(returns - V) / Var(returns)`` of the critic's values at collection,
once per rollout (1: the critic predicts the returns; 0: no better than their mean; negative: worse)."""
HEALTH = UPDATE_STATS[3:]  # PPO's health, after the losses


def gae(rewards: torch.Tensor, values: torch.Tensor, next_value: torch.Tensor, gamma: float, lam: float,
        not_done: torch.Tensor | None = None):
    """Generalized advantage estimation over time axis 0: returns ``(advantages, returns)``.

    ``rewards`` and ``values`` are (T, ...); ``next_value`` (...) is the value after the last
    step (0 when the episode ends there); ``not_done`` (T, ...) is 0 where step ``t`` ended an
    episode. ``delta_t = r_t + gamma V_{t+1} - V_t``; ``A_t = delta_t + gamma lambda A_{t+1}``;
    returns are ``A + V``. Example (one step, ``gamma = 0.5``): r = 1, V = 0, next 2 -> A = 2.
    """
    T = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    last = torch.zeros_like(next_value)
    nd = torch.ones_like(rewards) if not_done is None else not_done.to(rewards.dtype)
    for t in reversed(range(T)):  # the recursion runs backwards in time
        nxt = next_value if t == T - 1 else values[t + 1]
        delta = rewards[t] + gamma * nxt * nd[t] - values[t]
        last = delta + gamma * lam * nd[t] * last
        adv[t] = last
    return adv, adv + values


def clipped_surrogate(logp: torch.Tensor, old_logp: torch.Tensor, adv: torch.Tensor, clip: float,
                      mask: torch.Tensor | None = None) -> torch.Tensor:
    """PPO's loss ``-mean(min(rho A, clip(rho, 1-eps, 1+eps) A))`` with ``rho = exp(logp - old)``."""
    ratio = torch.exp(logp - old_logp)
    surr = torch.min(ratio * adv, ratio.clamp(1 - clip, 1 + clip) * adv)
    return -_mean(surr, mask)


def value_loss(values, old_values, targets, clip: float, delta: float, mask=None) -> torch.Tensor:
    """Clipped Huber value loss (MAPPO): max of the unclipped and clipped errors' Huber losses."""
    clipped = old_values + (values - old_values).clamp(-clip, clip)
    huber = nn.functional.huber_loss
    lo = huber(values, targets, reduction="none", delta=delta)
    lc = huber(clipped, targets, reduction="none", delta=delta)
    return _mean(torch.max(lo, lc), mask)


def _mean(x, mask):
    if mask is None:
        return x.mean()
    m = mask.to(x.dtype)
    return (x * m).sum() / m.sum().clamp(min=1)


class ValueNorm(nn.Module):
    """Running mean and std of value targets (MAPPO's ``ValueNorm``, debiased EMA).

    ``update(x)`` folds a batch in with weight ``1 - beta``; ``normalize(x)`` and
    ``denormalize(x)`` map between returns and the critic's output scale.
    """

    def __init__(self, beta: float = 0.999, eps: float = 1e-5):
        super().__init__()
        self.beta, self.eps = beta, eps
        self.register_buffer("mean", torch.zeros((), dtype=torch.float64))
        self.register_buffer("mean_sq", torch.zeros((), dtype=torch.float64))
        self.register_buffer("debias", torch.zeros((), dtype=torch.float64))

    def _stats(self):
        d = self.debias.clamp(min=self.eps)
        mean, sq = self.mean / d, self.mean_sq / d
        return mean, (sq - mean**2).clamp(min=1e-2)

    @torch.no_grad()
    def update(self, x: torch.Tensor, mask: torch.Tensor | None = None) -> None:
        x = x.double() if mask is None else x.double()[mask]
        if x.numel() == 0:
            return
        self.mean.mul_(self.beta).add_((1 - self.beta) * x.mean())
        self.mean_sq.mul_(self.beta).add_((1 - self.beta) * (x**2).mean())
        self.debias.mul_(self.beta).add_(1 - self.beta)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        mean, var = self._stats()
        return ((x.double() - mean) / var.sqrt()).to(x.dtype)

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        mean, var = self._stats()
        return (x.double() * var.sqrt() + mean).to(x.dtype)


class RolloutStorage:
    """Per-step named tensors of shape (B, ...), stacked to (T, B, ...) and cut into minibatches.

    >>> s = RolloutStorage(); s.add(x=torch.zeros(4, 3)); s.add(x=torch.ones(4, 3))
    >>> s.stacked()["x"].shape
    torch.Size([2, 4, 3])
    """

    def __init__(self):
        self.steps: list[dict[str, torch.Tensor]] = []

    def add(self, **tensors: torch.Tensor) -> None:
        self.steps.append({k: v.detach() for k, v in tensors.items()})

    def __len__(self) -> int:
        return len(self.steps)

    def stacked(self) -> dict[str, torch.Tensor]:
        return {k: torch.stack([s[k] for s in self.steps]) for k in self.steps[0]}

    @staticmethod
    def minibatches(data: dict[str, torch.Tensor], num_minibatches: int, generator: torch.Generator):
        """Flatten (T, B, ...) to rows and yield ``num_minibatches`` random disjoint row sets."""
        flat = {k: v.reshape(-1, *v.shape[2:]) for k, v in data.items()}
        rows = next(iter(flat.values())).shape[0]
        order = torch.randperm(rows, generator=generator)
        for idx in order.chunk(min(num_minibatches, rows)):  # index_select: the rows of v[idx], faster
            yield {k: v.index_select(0, idx) for k, v in flat.items()}


def sample(logits: torch.Tensor, generator: torch.Generator):
    """Categorical samples and their log-probabilities via the Gumbel-max trick (seeded)."""
    u = torch.rand(logits.shape, generator=generator, dtype=logits.dtype).clamp(1e-10, 1.0)
    a = (logits - torch.log(-torch.log(u))).argmax(-1)
    logp = torch.gather(torch.log_softmax(logits, -1), -1, a.unsqueeze(-1)).squeeze(-1)
    return a, logp


def explained_variance(values: torch.Tensor, returns: torch.Tensor, mask: torch.Tensor | None = None) -> float:
    """``1 - Var(returns - values) / Var(returns)`` over the masked entries (NaN when the returns do not vary)."""
    if mask is not None:
        values, returns = values[mask], returns[mask]
    var = returns.double().var(correction=0)
    if returns.numel() == 0 or not var > 0:
        return float("nan")
    return float(1 - (returns - values).double().var(correction=0) / var)


class NonFiniteError(ValueError):
    """A PPO update met a non-finite loss or gradient; raised before the optimizer steps."""


def ppo_update(data, evaluate, actor: nn.Module, critic: nn.Module, optimizer, cfg: PPOConfig,
               value_norm: ValueNorm, generator: torch.Generator, epochs: int | None = None,
               distribution=None) -> dict[str, float]:
    """Run PPO on one level's rollout; returns :data:`UPDATE_STATS` (the losses and PPO's health).

    ``data`` (T, B, ...) must hold ``actions``, ``logp``, ``values`` (normalised critic
    outputs at collection), ``returns`` (raw), ``advantages`` and ``mask`` (alive agents).
    ``evaluate(minibatch) -> (logits, values)`` recomputes the networks on a minibatch;
    ``distribution(out, actions) -> (log-probabilities, entropies)`` replaces the categorical over
    ``logits`` (the drone executor's Gaussian, :func:`masp_lite.algos.drone_trainer.gaussian`).
    Advantages are standardised over the alive agents of the whole rollout. ``epochs``
    overrides ``cfg.ppo_epochs``. The health statistics are computed without gradients from tensors
    the update computes anyway, and draw no random number: they change nothing in training.
    """
    mask_all = data["mask"]
    adv = data["advantages"]
    m = adv[mask_all]
    with torch.no_grad():  # the critic's values at collection are the returns minus the (raw) advantages
        ev = explained_variance(data["returns"] - adv, data["returns"], mask_all)
    data = dict(data, advantages=(adv - m.mean()) / (m.std() + 1e-8) if m.numel() > 1 else adv,
                targets=value_norm.normalize(data["returns"]))
    stats = dict.fromkeys(UPDATE_STATS[:5], 0.0)
    n = 0
    for _ in range(cfg.ppo_epochs if epochs is None else epochs):
        for mb in RolloutStorage.minibatches(data, cfg.num_minibatches, generator):
            out, values = evaluate(mb)
            if distribution is not None:
                logp, entropy = distribution(out, mb["actions"])
                entropy = _mean(entropy, mb["mask"])
            else:
                logp_all = torch.log_softmax(out, dim=-1)
                logp = torch.gather(logp_all, -1, mb["actions"].unsqueeze(-1)).squeeze(-1)
                entropy = _mean(-(logp_all.exp() * logp_all).sum(-1), mb["mask"])
            pl = clipped_surrogate(logp, mb["logp"], mb["advantages"], cfg.clip, mb["mask"])
            vl = value_loss(values, mb["values"], mb["targets"], cfg.clip, cfg.huber_delta, mb["mask"])
            loss = pl + cfg.value_coef * vl - cfg.entropy_coef * entropy
            for name, x in (("policy loss", pl), ("value loss", vl), ("entropy", entropy)):
                if not torch.isfinite(x):
                    raise NonFiniteError(f"the {name} is {x.item()}")
            optimizer.zero_grad()
            loss.backward()
            for name, net in (("policy", actor), ("critic", critic)):
                norm = nn.utils.clip_grad_norm_(net.parameters(), cfg.max_grad_norm)
                if not torch.isfinite(norm):
                    raise NonFiniteError(f"the {name}'s gradient norm is {norm.item()}")
            optimizer.step()
            kl, clipped = _health(logp, mb["logp"], cfg.clip, mb["mask"])
            for k, x in zip(UPDATE_STATS, (pl.item(), vl.item(), entropy.item(), kl, clipped)):
                stats[k] += x
            n += 1
    return {**{k: v / max(n, 1) for k, v in stats.items()}, "explained_variance": ev}


@torch.no_grad()
def _health(logp: torch.Tensor, old_logp: torch.Tensor, clip: float, mask) -> tuple[float, float]:
    """``(approximate KL, clip fraction)`` of one minibatch (:data:`UPDATE_STATS`), from its log-probabilities."""
    log_ratio = logp - old_logp
    ratio = log_ratio.exp()
    kl = _mean((ratio - 1) - log_ratio, mask)
    clipped = _mean(((ratio - 1).abs() > clip).to(logp.dtype), mask)
    return kl.item(), clipped.item()
