"""``masp``: the trained Goal Matcher and executor acting on a particle world.

The networks are :class:`~masp_lite.nets.masp.MASPNets`, loaded from a weights file
(:mod:`masp_lite.weights`: the shipped one for the scenario unless ``checkpoint`` says
otherwise). Every ``global_step`` environment steps the Goal Matcher's scores become one
goal per agent (:mod:`masp_lite.nets.decoding`); every step the executor acts towards it
with a fresh random group division, as in training.

The paper's ablations and its goal-based RL baselines are the same policy around weights
of another :class:`~masp_lite.config.NetConfig` (``method=``; the method table,
:data:`masp_lite.policies.METHODS`, gives each one's settings): ``masp-rg`` (random
goals), ``gm-mlp`` and ``cae-mlp`` (an MLP instead of a graph, for one team size);
``h-mappo`` (Hungarian goals, an executor over the nearest agents), ``htamp`` (MLPs at both
levels, flat observations), ``mage-x`` (goals once, at the start, by an attention graph
network; an executor on an attention-selected subgraph), and the goal-free ``mappo``
(attention over all agents and landmarks) and ``darl1n`` (one-hop neighbourhoods). Their default
weights are their training seed 0, packaged (:func:`masp_lite.weights.method_checkpoint`); each
method refuses another's weights, so a record never names the wrong method.
"""
from __future__ import annotations

import torch

from ..algos.goal_sources import DECODES, goal_source
from ..nets.decoding import joint_argmax
from ..nets.goal_draw import sequential_sample
from ..nets.masp import MASPNets
from ..weights import load_weights, method_checkpoint
from . import learned_methods

__all__ = ["MASPPolicy", "ABLATIONS", "BASELINES", "VARIANTS", "METHOD_SETTINGS"]

_LEARNED = learned_methods("particle")
#: Views of the method table (:data:`masp_lite.policies.METHODS`), not tables of their own: every learned
#: particle method -> the NetConfig settings its weights must have; the ablations and the RL baselines among
#: them; and the training settings that make each (its ``nets`` and ``train``, e.g. ``mage-x``'s long period).
VARIANTS = {m: dict(e["nets"]) for m, e in _LEARNED.items()}
ABLATIONS = {m: VARIANTS[m] for m, e in _LEARNED.items() if e.get("group") == "ablation"}
BASELINES = {m: VARIANTS[m] for m, e in _LEARNED.items() if e.get("group") == "baseline"}
METHOD_SETTINGS = {m: {**e["nets"], **e.get("train", {})} for m, e in _LEARNED.items()}


class MASPPolicy:
    """Trained Goal Matcher + executor on a particle world (``method``: ``masp`` or a variant of the table).

    ``checkpoint``: a weights file (default: the shipped one for the world's scenario, see
    :mod:`masp_lite.weights`; a variant's packaged seed 0). ``seed`` seeds the random group division. ``global_step``
    overrides the checkpoint's Goal Matcher period. ``deterministic``: take the most likely
    goals and action (the paper's "highest matching score"); ``False`` samples both.
    ``decode``: how the Goal Matcher's scores become goals (:mod:`masp_lite.nets.decoding`):
    ``"joint"`` (default) gives the alive agents distinct goals — the assignment with the
    least summed squared ``-log`` score, or the sequential draw of training when sampling; ``"independent"`` lets
    every agent take its own best goal, duplicates allowed (the paper's literal wording);
    ``"hungarian"`` bypasses the Goal Matcher and takes the Hungarian assignment
    (:func:`masp_lite.algos.assignment.hungarian`, the goals of ``h-greedy`` and of R_GM's
    reference) every global step (an agent it leaves without a goal, when a shrinking team
    has more agents than unreached landmarks, heads for its nearest landmark). That is not
    MASP: it is a diagnostic that tells the two levels apart (the executor's share of a
    gap to ``h-greedy`` versus the Goal Matcher's).
    ``resample`` (random goals only, ``masp-rg``): redraw them every global step; by default
    they are drawn once per episode (and again when the team changes), the reading of "MASP
    w. RG" that fits the paper's "consistently assigns different goals" and its SR of 1.
    With a team change (``mpe-20to10``, ...) the success rate counts landmarks ever
    reached, so the Goal Matcher's choice is restricted to landmarks not reached yet (all
    of them once every one has been reached); fixed teams choose among all landmarks.
    """

    kind = "particle"  # the world kind; the drone policy (:mod:`.drone_masp`) is this class with a Gaussian action

    def __init__(self, world, checkpoint: str | None = None, seed: int = 0, global_step: int | None = None,
                 deterministic: bool = True, any_scenario: bool = False, decode: str = "joint",
                 resample: bool = False, method: str = "masp"):
        table = learned_methods(self.kind)
        if method not in table:
            raise ValueError(f"method: expected one of {sorted(table)}, got {method!r}")
        name = self.method = method
        if getattr(world.scenario, "kind", None) != self.kind:
            raise ValueError(f"{name}: expected a {self.kind} world ({'drone' if self.kind == 'drone' else 'mpe'}-* "
                             "scenario)")
        self.world = world
        if isinstance(checkpoint, torch.nn.Module):  # networks in memory (:meth:`from_nets`): taken as they are
            self.nets, self.meta = checkpoint, {}
        else:
            if checkpoint is None and table[name]["weights"] != "shipped":
                checkpoint = method_checkpoint(name, world.scenario, table[name]["weights"])
            self.nets, self.meta = load_weights(checkpoint, scenario=world.scenario, any_scenario=any_scenario)
            self.nets.eval()
            self._check_variant(name, {m: e["nets"] for m, e in table.items()})
        self.resample = bool(resample)
        gs = self.nets.arch["global_step"] if global_step is None else global_step
        if isinstance(gs, bool) or not isinstance(gs, int) or gs < 1:
            raise ValueError(f"global_step: expected a positive int, got {global_step!r}")
        self._setup(gs, deterministic, seed, decode)

    def _check_variant(self, name, variants):
        c, want = self.nets.config, variants[name]
        got = {k: getattr(c, k) for k in want}
        if got != want:
            other = [m for m, v in variants.items() if all(getattr(c, k) == x for k, x in v.items())]
            raise ValueError(f"{name}: the checkpoint's networks are {got}, expected {want}"
                             + (f"; these are {other[0]} weights: use that method" if other else ""))
        if c.fixed_size and self.world.num_agents != c.team_size:
            raise ValueError(f"{name}: these weights are an MLP built for {c.team_size} agents (a fixed input "
                             f"size), the scenario has {self.world.num_agents}; evaluate it at N = {c.team_size} "
                             "only")

    def _setup(self, global_step, deterministic, seed, decode):
        if decode not in DECODES:
            raise ValueError(f"decode: expected one of {list(DECODES)}, got {decode!r}")
        self.global_step, self.deterministic, self.seed = global_step, bool(deterministic), int(seed)
        self.decode = decode
        self.scale = self.world.scenario.world_size / 2
        self.generator = torch.Generator().manual_seed(self.seed)
        self.goals = None
        # None: the Goal Matcher decodes the goals; else an ablation's or a baseline's source, or the diagnostic
        self.goal_source = goal_source(self.nets.config.goal_matcher, decode, self.resample)

    @classmethod
    def from_nets(cls, world, nets: MASPNets, seed: int = 0, deterministic: bool = True,
                  decode: str = "joint") -> "MASPPolicy":
        """A policy around networks in memory, whatever their variant (used by training's periodic evaluation)."""
        return cls(world, checkpoint=nets, seed=seed, deterministic=deterministic, decode=decode)

    def reset(self, obs) -> None:
        self.goals = None

    def _pick(self, logits):
        if self.deterministic:
            return logits.argmax(-1)
        u = torch.rand(logits.shape, generator=self.generator).to(logits.device)
        return (logits - torch.log(-torch.log(u.clamp(1e-10, 1.0)))).argmax(-1)

    def _goals(self, logits, alive, mask):
        if self.decode == "independent":
            return self._pick(logits)
        if self.deterministic:
            return joint_argmax(logits, alive, mask)
        return sequential_sample(logits.cpu(), alive.cpu(), self.generator, None if mask is None else mask.cpu())[0] \
            .to(logits.device)

    @torch.inference_mode()
    def choose_goals(self, obs) -> torch.Tensor:
        """The goals (B, N) this policy's goal source picks for ``obs``: one global step's choice.

        The Goal Matcher decoded by ``decode``, or :attr:`goal_source`'s (:mod:`masp_lite.algos.goal_sources`:
        the Hungarian diagnostic, or the weights' own source: random goals, ``h-mappo``'s Hungarian ones, none
        for the goal-free baselines). :meth:`act` calls it every global step;
        the drone planners' ``goals="masp"`` (:mod:`masp_lite.policies.goal_sources`) call it to fly
        MASP's goals with their own flight, so the two read one decoding."""
        mask = None
        if self.world.scenario.varying:  # landmarks already reached count for SR; pick among the rest
            mask = ~obs["reached"] | obs["reached"].all(-1, keepdim=True)
        if self.goal_source is not None:
            return self.goal_source(obs, self.goals, mask, self.generator)
        return self._goals(self.nets.gm_logits(obs, self.scale, mask), obs["alive"], mask)

    @torch.inference_mode()
    def act(self, obs) -> torch.Tensor:
        due = obs["t"] % self.global_step == 0
        if self.goals is None or bool(due.any()):  # goals None throughout for the goal-free baselines
            new = self.choose_goals(obs)
            self.goals = new if self.goals is None else torch.where(due.unsqueeze(-1), new, self.goals)
        B, N = obs["alive"].shape
        perm = torch.rand(B, N, generator=self.generator).argsort(-1).to(obs["alive"].device)
        return self.action(self.nets.cae_logits(self.nets.cae_inputs(obs, self.goals, perm)), obs)

    def action(self, out, obs) -> torch.Tensor:
        """The world's actions from the executor's output: MPE's action ids (the most likely, or sampled;
        dropped agents send 0)."""
        actions = self._pick(out)
        return torch.where(obs["alive"], actions, torch.zeros_like(actions))
