"""The Goal Matcher taught an assignment by imitation: ``masp-minmax``'s stage (ours, not the paper's).

**Why.** Steps waits for the *last* landmark, so the min-max ("bottleneck") assignment re-solved every
global step (``h-bottleneck``: :func:`~masp_lite.algos.team.bottleneck` and straight flight) needs fewer
Steps than MASP at N = 50, and MAPPO on R_GM (eq. 1) with the training draw does not bring the Goal Matcher
near it within CPU-hours (research log, 2026-12-03): R_GM's reference minimises a total, and a min-max
reference gives every agent but the one on the longest trip the same reward. The learned assignment
methods that scale to hundreds of agents start from a solver's assignments and then fine-tune by RL; this
stage is the first half of that recipe, with the min-max solver as the teacher (:data:`TEACHERS`, chosen
by ``ImitationConfig.imitate``). The second half is not kept: MAPPO on R_GM after the imitation (the
paper's fine-tune, Goal Matcher alone) took back the imitation's gain in every design measured, with or
without the margin below kept beside PPO's loss (research log, 2026-12-07; ``experiments/minmax_finetune.py``).

**What is learned**, on layouts the world generates, with the teacher's goals ``g*`` and longest trip ``t*``:
a structured margin on the evaluation's decoding (:func:`~masp_lite.nets.decoding.joint_argmax`, the
assignment of least ``C(s) = sum_k (-log S_k(s_k))^2``), :func:`decoding_margin_loss`. It is 0 exactly
when every assignment that sends an agent farther than ``t*`` costs at least ``imitation_margin`` per such
agent more than the cheapest one that does not: the decoding then keeps the teacher's longest trip. It leaves
the choice among the many assignments with that longest trip to the scores, which is why it is learnable: on
validation layouts the Hungarian assignment on distances to the 16th power keeps the min-max trip within
0.2 % yet gives only 44 % of the agents ``bottleneck``'s goal (research log, 2026-12-07).

Tried and not kept (research log, 2026-12-07; :func:`draw_nll` stays for research scripts, which change
:meth:`ImitationTrainer.loss` in a subclass): the negative log-likelihood of the teacher's goals under the
draw the Goal Matcher acts by in training (:mod:`masp_lite.nets.goal_draw`: agents in a random order, each
choosing from its categorical restricted to the goals earlier agents have not taken), ``L = -1/|K| sum_k log
softmax(z_k over the goals not taken before k)[g*_k]`` (:func:`~masp_lite.nets.goal_draw.conditional_logits`
with the teacher's goals standing in for the picks, one fresh order per layout and step), with every goal
within ``t*`` counted as right (:func:`within_longest_trip`) or not. Neither moved the decoding towards the
min-max trip at N = 50.

**On which layouts**: a fresh episode start in every world each iteration (no step simulated: cheap).
DAgger's states (every global step of episodes the policy flies to its own decoded goals) were tried after
the starts and not kept: on the retrained MASP they undid the starts' gain (research log, 2026-12-07;
``experiments/minmax_imitation.py --states rollout``). Agents the teacher leaves without a goal (more alive
agents than allowed goals) and dropped agents are left out and block no goal. Only the Goal Matcher's actor
learns (its optimizer, MAPPO's step size and gradient clip); the executor, both critics and their value
normalisations stay as they were.
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from ..nets.goal_draw import MASKED, allowed_goals, conditional_logits
from .mappo import NonFiniteError
from .masp_trainer import MASPTrainer
from .team import bottleneck

__all__ = ["TEACHERS", "teacher_goals", "random_rank", "within_longest_trip", "draw_nll", "decoding_margin_loss",
           "ImitationTrainer"]

TEACHERS = {"h-bottleneck": bottleneck}
"""``ImitationConfig.imitate`` -> the assignment ``(agent_pos, goal_pos, agent_mask, goal_mask) -> (B, N)``,
``-1`` for no goal."""


def teacher_goals(teacher: str, obs: dict, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """The teacher's goals (B, N) for the alive agents of ``obs`` among the allowed goals (``-1``: none)."""
    if teacher not in TEACHERS:
        raise ValueError(f"imitate: expected one of {sorted(TEACHERS)}, got {teacher!r}")
    return TEACHERS[teacher](obs["agent_pos"], obs["landmark_pos"], obs["alive"], goal_mask)


def random_rank(batch: int, agents: int, generator: torch.Generator) -> torch.Tensor:
    """A uniformly random drawing order per world (B, N): each agent's position (0 draws first), drawn as
    :func:`~masp_lite.nets.goal_draw.sequential_sample` draws it."""
    return torch.rand(batch, agents, generator=generator).argsort(-1).argsort(-1)


def within_longest_trip(obs: dict, targets: torch.Tensor, goal_mask: torch.Tensor | None = None) -> torch.Tensor:
    """(B, N, M) bool: the allowed goals no farther from each agent than the teacher's longest trip in its layout,
    and the teacher's own goal: the pairs an assignment as short as the teacher's at its longest may use."""
    d = torch.cdist(obs["agent_pos"], obs["landmark_pos"])
    labelled = obs["alive"] & (targets >= 0)
    trip = torch.gather(d, -1, targets.clamp(min=0).unsqueeze(-1)).squeeze(-1)
    longest = trip.masked_fill(~labelled, 0.0).amax(-1)                               # (B,)
    own = torch.nn.functional.one_hot(targets.clamp(min=0), d.shape[-1]).bool()
    return ((d <= longest[:, None, None]) & allowed_goals(goal_mask, d).unsqueeze(1)) | own


def draw_nll(logits: torch.Tensor, targets: torch.Tensor, alive: torch.Tensor, rank: torch.Tensor | None = None,
             goal_mask: torch.Tensor | None = None, accept: torch.Tensor | None = None):
    """``(loss, entropy)``: the mean negative log-likelihood, over the labelled agents, that each picks a goal
    counted as right, and the mean entropy of the categoricals it reads.

    ``logits`` (B, N, M) the Goal Matcher's; ``targets`` (B, N) the teacher's goals (``-1``: none); ``alive``
    (B, N); ``rank`` (B, N) the draw's order (:func:`random_rank`; ``None``: every agent's own categorical over
    all allowed goals, a plain cross-entropy); ``goal_mask`` (B, M) the goals that may be chosen (``None``: all);
    ``accept`` (B, N, M) bool the goals counted as right for each agent (``None``: the teacher's goal alone; it
    must hold it)."""
    if targets.shape != logits.shape[:2] or alive.shape != targets.shape:
        raise ValueError(f"draw_nll: expected targets and alive of shape {tuple(logits.shape[:2])}, got "
                         f"{tuple(targets.shape)} and {tuple(alive.shape)}")
    labelled = alive & (targets >= 0)
    if rank is None:
        restricted = logits.masked_fill(~allowed_goals(goal_mask, logits).unsqueeze(1), MASKED)
    else:
        restricted = conditional_logits(logits, targets, rank, labelled, goal_mask)
    logp = torch.log_softmax(restricted, -1)
    if accept is None:
        nll = -torch.gather(logp, -1, targets.clamp(min=0).unsqueeze(-1)).squeeze(-1)
    else:
        nll = -torch.logsumexp(logp.masked_fill(~accept, float("-inf")), -1).masked_fill(~labelled, 0.0)
    entropy = -(logp.exp() * logp).sum(-1)
    w = labelled.to(logp.dtype)
    count = w.sum().clamp(min=1)
    return (nll * w).sum() / count, (entropy * w).sum() / count


def decoding_margin_loss(logits: torch.Tensor, over: torch.Tensor, alive: torch.Tensor,
                         goal_mask: torch.Tensor | None = None, margin: float = 1.0, power: float = 2.0):
    """``(loss, entropy)``: a structured margin on the evaluation's decoding, ``(1 / |K|) * sum_b [C(s_f) -
    min_s (C(s) - margin * |{k: over[k, s_k]}|)]`` (>= 0), and the mean entropy of the agents' categoricals.

    ``C(s) = sum_k (-log S_k(s_k)) ** power`` is the cost :func:`~masp_lite.nets.decoding.joint_argmax` minimises
    (``power`` 2: the policies' decoding); ``over`` (B, N, M) bool marks the pairs beyond the teacher's longest
    trip; ``s_f`` is the cheapest assignment without such a pair (the teacher's is one, so it exists). The loss
    is 0 when every assignment that uses a pair beyond the teacher's longest trip costs at least ``margin`` per
    such pair more than ``s_f``: the decoding then returns an assignment as short as the teacher's at its
    longest, its choice among the ties left to the scores. Two ``linear_sum_assignment`` calls per layout
    find ``s_f`` and the most violating ``s``; the gradient flows through ``C`` at both."""
    allowed = allowed_goals(goal_mask, logits)
    logp = torch.log_softmax(logits.masked_fill(~allowed.unsqueeze(1), MASKED), -1)
    cost = (-logp).clamp(min=0) ** power
    c, o = cost.detach().double().numpy(), over.numpy()
    am, gm = alive.numpy(), allowed.numpy()
    total = cost.new_zeros(())
    for b in range(c.shape[0]):  # scipy solves one matrix at a time
        rows, cols = np.flatnonzero(am[b]), np.flatnonzero(gm[b])
        if len(rows) == 0 or len(cols) == 0:
            continue
        cb, ob = c[b][np.ix_(rows, cols)], o[b][np.ix_(rows, cols)]
        big = (cb.sum() + margin * cb.size + 1.0) * 2  # more than any assignment's cost within the longest trip
        rf, cf = linear_sum_assignment(np.where(ob, big, cb))
        rv, cv = linear_sum_assignment(cb - margin * ob)
        total = total + cost[b, rows[rf], cols[cf]].sum() - cost[b, rows[rv], cols[cv]].sum() \
            + margin * float(ob[rv, cv].sum())
    count = alive.sum().clamp(min=1)
    entropy = (-(logp.exp() * logp).sum(-1) * alive).sum() / count
    return total / count, entropy


class ImitationTrainer(MASPTrainer):
    """A run's iterations as imitation: layouts, the teacher's goals, gradient steps on :meth:`loss`.

    :func:`masp_lite.training.train` uses it when ``imitate`` is set (``train --set imitate=h-bottleneck``);
    everything else of a run (checkpoints, exact resume, periodic evaluation, the manifest) is the same. A row
    of ``progress.csv`` holds the loss (``gm_policy_loss``) and the entropy of the categoricals it reads
    (``gm_entropy``)."""

    def __init__(self, scenario: str, cfg, seed: int = 0, overrides: dict | None = None):
        super().__init__(scenario, cfg, seed, overrides)
        im = cfg.imitation
        if im.imitate not in TEACHERS:
            raise ValueError(f"imitate: expected one of {sorted(TEACHERS)}, got {im.imitate!r}")
        if not self.gm_trained:
            raise ValueError(f"imitate: these networks have no Goal Matcher to train (goal_matcher="
                             f"{cfg.net.goal_matcher!r}); expected a method with one (masp-minmax, masp)")
        if cfg.run.train_executor:
            raise ValueError("imitate: the imitation trains the Goal Matcher alone; expected --set "
                             "train_executor=false (masp-minmax's own setting)")

    def layouts(self) -> tuple[dict, dict]:
        """``(obs, stats)``: this iteration's layouts as one observation batch (S, ...), ``num_envs`` fresh
        episode starts, and the SR, Steps and CR of a training rollout (NaN: nothing is simulated)."""
        obs = self.world.reset()
        return {k: obs[k] for k in self.obs_keys}, dict.fromkeys(("sr", "steps", "cr"), float("nan"))

    def goal_mask(self, obs: dict) -> torch.Tensor | None:
        """The goals a layout allows, as the policy allows them: a shrinking team's landmarks not reached yet."""
        if not self.world.scenario.varying:
            return None
        return ~obs["reached"] | obs["reached"].all(-1, keepdim=True)

    def loss(self, logits, obs: dict, targets, goal_mask):
        """``(loss, entropy)`` of one batch of layouts: :func:`decoding_margin_loss`, the pairs past the
        teacher's longest trip marked by :func:`within_longest_trip`."""
        over = ~within_longest_trip(obs, targets, goal_mask)
        return decoding_margin_loss(logits, over, obs["alive"] & (targets >= 0), goal_mask,
                                    self.cfg.imitation.imitation_margin)

    def imitation_pass(self, obs: dict, weight: float = 1.0) -> tuple[float, float]:
        """One pass of gradient steps on :meth:`loss` (times ``weight``) over the layouts ``obs`` (S, ...), in
        batches of ``num_envs`` layouts, the teacher's goals computed first; returns the mean loss and entropy."""
        cfg, nets, g = self.cfg, self.nets, self.generator
        with torch.no_grad():
            mask = self.goal_mask(obs)
            targets = teacher_goals(cfg.imitation.imitate, obs, mask)
        losses, entropies = [], []
        for rows in torch.randperm(targets.shape[0], generator=g).split(cfg.run.num_envs):
            mb = {k: v[rows] for k, v in obs.items()}
            mb_mask = None if mask is None else mask[rows]
            logits = nets.gm_logits(mb, self.scale, mb_mask)
            loss, entropy = self.loss(logits, mb, targets[rows], mb_mask)
            if not torch.isfinite(loss):
                raise NonFiniteError(f"the imitation loss is {loss.item()}")
            self.gm_opt.zero_grad()
            (weight * loss).backward()
            norm = torch.nn.utils.clip_grad_norm_(nets.gm.parameters(), cfg.ppo.max_grad_norm)
            if not torch.isfinite(norm):
                raise NonFiniteError(f"the Goal Matcher's gradient norm is {norm.item()}")
            self.gm_opt.step()
            losses.append(loss.item())
            entropies.append(entropy.item())
        return sum(losses) / len(losses), sum(entropies) / len(entropies)

    def iteration(self) -> dict[str, float]:
        """One iteration: layouts, then :meth:`imitation_pass` over them."""
        obs, stats = self.layouts()
        loss, entropy = self.imitation_pass(obs)
        self.iterations += 1
        nan = float("nan")
        row = {"iteration": self.iterations, "env_steps": self.env_steps,
               **{f"train_{k}": v for k, v in stats.items()}, "gm_reward": nan, "cae_reward": nan,
               "gm_policy_loss": loss, "gm_entropy": entropy}
        self.last_row = row
        return row
