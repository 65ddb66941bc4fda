"""Can MASP's networks hold a policy with SR >= 0.99 on mpe-5? Imitate the search and see.

Usage (from the repository root)::

    python -m experiments.mpe5_distill expert              # Goal Matcher + search: the teacher
    python -m experiments.mpe5_distill dagger --out DIR    # teach the executor by DAgger
    python -m experiments.mpe5_distill probe --labels DIR/labels.pt

Every MAPPO run on mpe-5 ends at SR 0.965-0.980 (``docs/research-log.md``), while the search of
:mod:`experiments.mpe5_oracle` reaches 0.998. This script asks whether the gap lies in the networks (a
reactive executor, one observation at a time, cannot express what lookahead does) or in
MAPPO (it does not find such a policy). It is an experiment, not the paper's training, and
its weights are not shipped.

The teacher takes the shipped Goal Matcher's goals and chooses each agent's action by
search. ``--teacher copy`` is ``experiments.mpe5_oracle --per-agent`` with those goals: the first
action of agent ``k``'s best copy. That label also depends on which later random actions
of the copy paid off, so it is noisy. ``--teacher action`` (default, :class:`ActionSearch`)
tries each of the 5 first actions with its own copies and keeps the velocity controller's
action unless another one scores ``--margin`` more.

``expert`` evaluates the teacher like ``evaluate --method masp`` (seeds 0 1 2, 100 episodes
each). ``dagger`` trains the shipped executor's actor by DAgger (Ross et al., 2011): each
round plays episodes on training seeds (1000 and up), taking each agent's action from the
teacher with probability ``beta`` (1 in the first round, halved every round) and from the
current executor otherwise. Every visited state is labelled with the teacher's action, the
executor is fitted by cross-entropy to all the labels so far (``labels.pt``), and it is
evaluated like the teacher. The Goal Matcher and both critics stay as shipped. ``probe``
asks whether the teacher's departures from the controller can be predicted from the state
at all (:func:`probe`).

Written by hand: the teacher needs the world's internal state (see :mod:`experiments.mpe5_oracle`).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from experiments.mpe5_oracle import SearchOracle, arrival_actions, copy_state
from masp_lite.envs import ACTION_DIRECTIONS, make
from masp_lite.evaluation import EpisodeLog, collision_rate, rollout, steps, success_rate
from masp_lite.policies.masp import MASPPolicy
from masp_lite.weights import load_weights, save_weights

KEYS = ("agent_pos", "agent_vel", "landmark_pos", "obstacle_pos", "alive")


class GoalSearch(SearchOracle):
    """The per-agent search, heading for goals it is given instead of the Hungarian ones."""

    given: torch.Tensor | None = None

    def goals(self, obs) -> torch.Tensor:
        return self.given


class ActionSearch:
    """Per agent, the first action whose best continuation scores highest.

    For agent ``k`` and each first action ``a`` it runs ``M`` copies of the episode to the
    horizon: ``k`` plays ``a``, then the controller with random actions at rate
    ``noise * m / (M - 1)`` in copy ``m``; every other agent follows the controller. The
    copies are scored as in :class:`SearchOracle`. ``Q(a)`` is the best score among ``a``'s
    copies; the label is the controller's own action unless ``max Q`` beats its ``Q`` by more
    than ``margin``, and ``argmax Q`` then. Unlike
    the first action of the single best copy, this label does not depend on which later
    random actions happened to pay off.
    """

    def __init__(self, world, copies: int = 25, noise: float = 0.5, contact_weight: float = 1.0,
                 coverage_weight: float = 0.5, seed: int = 0, margin: float = 0.0):
        self.world, self.M, self.noise, self.margin = world, int(copies), float(noise), float(margin)
        self.contact_weight, self.coverage_weight = float(contact_weight), float(coverage_weight)
        self.A = len(ACTION_DIRECTIONS)
        self.K = world.num_agents * self.A * self.M
        self.sim = make(world.scenario, num_envs=world.num_envs * self.K, seed=seed)
        self.sim.reset(seed=seed)
        self.generator = torch.Generator().manual_seed(seed)
        self.given = None

    def reset(self, obs):
        pass

    def act(self, obs) -> torch.Tensor:
        w, sim, g = self.world, self.sim, self.generator
        B, N, A, M, K = w.num_envs, w.num_agents, self.A, self.M, self.K
        goal_pos_w = torch.gather(w.landmark_pos, 1, self.given.unsqueeze(-1).expand(B, N, 2))
        goal_pos = goal_pos_w.repeat_interleave(K, 0)
        copy_state(sim, w, K)
        p = torch.linspace(0, self.noise, M) if M > 1 else torch.zeros(1)
        p = (p.view(1, 1, M, 1) * torch.eye(N).view(N, 1, 1, N)).expand(N, A, M, N)   # only k is noisy
        p = p.reshape(1, K, N).expand(B, K, N).reshape(B * K, N)
        searcher = torch.eye(N, dtype=torch.bool).view(1, N, 1, 1, N).expand(B, N, A, M, N).reshape(B * K, N)
        forced = torch.arange(A).view(1, 1, A, 1, 1).expand(B, N, A, M, N).reshape(B * K, N)
        contacts = torch.zeros(B * K, dtype=torch.float64)
        covered = torch.zeros(B * K, dtype=torch.float64)
        first = True
        for _ in range(int(w.t.max()), w.horizon):
            a = arrival_actions(sim.agent_pos, sim.agent_vel, goal_pos)
            if first:
                a = torch.where(searcher, forced, a)
                first = False
            else:
                noisy = torch.rand(a.shape, generator=g) < p
                a = torch.where(noisy, torch.randint(0, A, a.shape, generator=g), a)
            _, info = sim.step(a)
            contacts += info["collisions"]
            covered += info["covered"].sum(-1)
        near = torch.cdist(sim.landmark_pos, sim.agent_pos).min(-1).values.sum(-1)
        score = 10 * sim.covered.sum(-1) - near - self.contact_weight * contacts + self.coverage_weight * covered
        q = score.view(B, N, A, M).max(-1).values                                  # (B, N, A)
        ctrl = arrival_actions(w.agent_pos, w.agent_vel, goal_pos_w)
        q_ctrl = torch.gather(q, -1, ctrl.unsqueeze(-1)).squeeze(-1)
        return torch.where(q_ctrl >= q.max(-1).values - self.margin - 1e-9, ctrl, q.argmax(-1))


class Teacher:
    """Shipped Goal Matcher for the goals, the search for the actions (:mod:`masp_lite.evaluation` policy interface)."""

    def __init__(self, world, nets, seed: int, candidates: int, kind: str = "action", **weights):
        self.student = MASPPolicy.from_nets(world, nets, seed=seed)
        if kind == "action":
            self.search = ActionSearch(world, max(1, candidates // 5), seed=seed, **weights)
        else:
            weights.pop("margin", None)
            self.search = GoalSearch(world, candidates, seed=seed, per_agent=True, **weights)

    def reset(self, obs):
        self.student.reset(obs)

    def act(self, obs):
        self.student.act(obs)                      # updates the Goal Matcher's goals
        self.search.given = self.student.goals
        return self.search.act(obs)


def evaluate(world_policy, scenario="mpe-5") -> dict:
    """Steps, SR and CR as ``evaluate`` computes them, for ``world_policy(world, seed)`` policies."""
    logs = []
    for seed in (0, 1, 2):
        world = make(scenario, num_envs=100, seed=seed)
        logs.append(rollout(world, world_policy(world, seed), 100, seed)[0])
    log = EpisodeLog.cat(logs)
    return {"Steps": float(steps(log).numpy().mean()), "SR": float(success_rate(log).numpy().mean()),
            "CR": float(collision_rate(log).numpy().mean())}


def collect(nets, seed: int, beta: float, candidates: int, kind: str, weights: dict, episodes: int = 100) -> dict:
    """One batch of episodes under the beta-mixture; every state labelled by the teacher."""
    world = make("mpe-5", num_envs=episodes, seed=seed)
    obs = world.reset(seed=seed)
    teacher = Teacher(world, nets, seed, candidates, kind, **weights)
    g = torch.Generator().manual_seed(seed)
    data = {k: [] for k in (*KEYS, "goals", "action")}
    for _ in range(world.horizon):
        student_a = teacher.student.act(obs)
        teacher.search.given = teacher.student.goals
        teacher_a = teacher.search.act(obs)
        for k in KEYS:
            data[k].append(obs[k].clone())
        data["goals"].append(teacher.student.goals.clone())
        data["action"].append(teacher_a.clone())
        pick = torch.rand(student_a.shape, generator=g) < beta
        obs, _ = world.step(torch.where(pick, teacher_a, student_a))
    return {k: torch.cat(v) for k, v in data.items()}


def fit(nets, data: dict, epochs: int, lr: float, seed: int, batch: int = 512) -> float:
    """Cross-entropy of the executor's actor on the teacher's actions (alive agents)."""
    params = list(nets.cae.parameters())
    opt = torch.optim.Adam(params, lr=lr)
    g = torch.Generator().manual_seed(seed)
    n = data["action"].shape[0]
    nets.train()
    last = 0.0
    for _ in range(epochs):
        order = torch.randperm(n, generator=g)
        total, count = 0.0, 0
        for i in range(0, n, batch):
            idx = order[i:i + batch]
            obs = {k: data[k][idx] for k in KEYS}
            goals = data["goals"][idx]
            perm = torch.rand(goals.shape, generator=g).argsort(-1)
            logits = nets.cae_logits(nets.cae_inputs(obs, goals, perm))
            alive = obs["alive"]
            loss = torch.nn.functional.cross_entropy(logits[alive], data["action"][idx][alive])
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(params, 10.0)
            opt.step()
            total, count = total + float(loss.detach()) * len(idx), count + len(idx)
        last = total / count
    nets.eval()
    return last


def controller_actions(data: dict) -> torch.Tensor:
    """The velocity controller's action for every labelled agent-step, toward its goal."""
    goal_pos = torch.gather(data["landmark_pos"], 1, data["goals"].unsqueeze(-1).expand_as(data["agent_pos"]))
    return arrival_actions(data["agent_pos"], data["agent_vel"], goal_pos)


def state_features(data: dict) -> torch.Tensor:
    """Everything the teacher knows, from each agent's point of view: (S, N, F).

    Own velocity and goal; every other agent's position, velocity and goal, nearest first;
    every obstacle and landmark, nearest first; the controller's action; the time step
    (``collect`` stores 100 worlds per step, 18 steps per batch)."""
    pos, vel, lms, obst = data["agent_pos"], data["agent_vel"], data["landmark_pos"], data["obstacle_pos"]
    S, N = data["goals"].shape
    goal = torch.gather(lms, 1, data["goals"].unsqueeze(-1).expand_as(pos))
    rel = pos.unsqueeze(1) - pos.unsqueeze(2)
    order = rel.norm(dim=-1).argsort(-1)[:, :, 1:]
    pick = lambda x: torch.gather(x, 2, order.unsqueeze(-1).expand(-1, -1, -1, x.shape[-1])).flatten(2)  # noqa: E731
    others = [pick(rel), pick(vel.unsqueeze(1) - vel.unsqueeze(2)), pick(goal.unsqueeze(1) - pos.unsqueeze(2))]
    def sorted_rel(points):
        r = points.unsqueeze(1) - pos.unsqueeze(2)
        o = r.norm(dim=-1).argsort(-1)
        return torch.gather(r, 2, o.unsqueeze(-1).expand(-1, -1, -1, 2)).flatten(2)
    t = ((torch.arange(S) // 100) % 18).float().view(S, 1, 1).expand(S, N, 1) / 18
    ctrl = torch.nn.functional.one_hot(controller_actions(data), 5).float()
    return torch.cat([vel, goal - pos, *others, sorted_rel(obst), sorted_rel(lms), ctrl, t], dim=-1)


def probe(data: dict, weight: float, steps: int, seed: int = 0) -> dict:
    """Can the teacher's departures from the controller be predicted from the state?

    Holds out episodes 80-99 of every 100 and fits two classifiers to the rest with the
    departures weighted ``weight`` times: the shipped executor's actor (its own inputs) and
    a 3 x 256 MLP on :func:`state_features`. For each: accuracy where the teacher kept the
    controller's action, and the share of departures it predicts exactly (recall) and of
    its own departures that are right (precision), on training and held-out episodes."""
    torch.manual_seed(seed)
    S, N = data["goals"].shape
    ctrl = controller_actions(data)
    depart = (ctrl != data["action"]) & data["alive"]
    held = (torch.arange(S) % 100) >= 80
    train_idx = torch.nonzero(~held).squeeze(1)
    nets, _ = load_weights(None, scenario=make("mpe-5", num_envs=1).scenario)
    X = state_features(data)
    mu, sd = X[~held].flatten(0, 1).mean(0), X[~held].flatten(0, 1).std(0) + 1e-6
    mlp = torch.nn.Sequential(torch.nn.Linear(X.shape[-1], 256), torch.nn.ReLU(), torch.nn.Linear(256, 256),
                              torch.nn.ReLU(), torch.nn.Linear(256, 256), torch.nn.ReLU(), torch.nn.Linear(256, 5))
    models = {"executor": (lambda i: nets.cae_logits(nets.cae_inputs({k: data[k][i] for k in KEYS}, data["goals"][i],
                                                                       torch.rand(len(i), N).argsort(-1))),
                           list(nets.cae.parameters())),
              "state MLP": (lambda i: mlp((X[i] - mu) / sd), list(mlp.parameters()))}
    out = {}
    for name, (forward, params) in models.items():
        opt = torch.optim.Adam(params, lr=1e-3)
        for _ in range(steps):
            i = train_idx[torch.randint(0, len(train_idx), (512,))]
            alive = data["alive"][i]
            ce = torch.nn.functional.cross_entropy(forward(i)[alive], data["action"][i][alive], reduction="none")
            w = 1 + (weight - 1) * depart[i][alive].float()
            loss = (ce * w).sum() / w.sum()
            opt.zero_grad()
            loss.backward()
            opt.step()
        with torch.no_grad():
            for part, mask in (("train", ~held), ("held out", held)):
                i = torch.nonzero(mask).squeeze(1)
                pred, alive, dep = forward(i).argmax(-1), data["alive"][i], depart[i]
                right, own = pred == data["action"][i], (pred != ctrl[i]) & alive
                out[f"{name}, {part}"] = {
                    "controller kept, accuracy": round(float(right[alive & ~dep].float().mean()), 3),
                    "departures, recall": round(float(right[dep].float().mean()), 3),
                    "own departures, precision": round(float(right[own].float().mean()), 3),
                    "departures": int(dep.sum())}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("expert", "dagger", "probe"))
    ap.add_argument("--labels", help="probe: a labels.pt written by dagger")
    ap.add_argument("--weight", type=float, default=10.0, help="probe: weight of the departures")
    ap.add_argument("--steps", type=int, default=3000, help="probe: gradient steps per classifier")
    ap.add_argument("--candidates", type=int, default=128)
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--batches", type=int, default=4, help="100-episode batches collected per round")
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--out", default="runs/distill")
    ap.add_argument("--contact-weight", type=float, default=0.3)
    ap.add_argument("--coverage-weight", type=float, default=1.0)
    ap.add_argument("--margin", type=float, default=1.0,
                    help="the action teacher keeps the controller's action unless another scores this much more")
    ap.add_argument("--teacher", choices=("action", "copy"), default="action",
                    help="label = best first action over its continuations, or first action of the best copy")
    a = ap.parse_args(argv)
    weights = {"contact_weight": a.contact_weight, "coverage_weight": a.coverage_weight, "margin": a.margin}
    torch.set_num_threads(1)
    nets, _ = load_weights(None, scenario=make("mpe-5", num_envs=1).scenario)
    nets.eval()
    start = time.perf_counter()
    if a.mode == "probe":
        print(json.dumps(probe(torch.load(a.labels), a.weight, a.steps), indent=1))
        return
    if a.mode == "expert":
        r = evaluate(lambda w, s: Teacher(w, nets, s, a.candidates, a.teacher, **weights))
        print(json.dumps({**r, "seconds": round(time.perf_counter() - start)}))
        return
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    print(json.dumps({"round": "shipped", **evaluate(lambda w, s: MASPPolicy.from_nets(w, nets, seed=s))}), flush=True)
    data = None
    for r in range(a.rounds):
        beta = 0.5 ** r
        for b in range(a.batches):
            new = collect(nets, 1000 + 100 * r + b, beta, a.candidates, a.teacher, weights)
            data = new if data is None else {k: torch.cat([data[k], new[k]]) for k in data}
        torch.save(data, out / "labels.pt")
        loss = fit(nets, data, a.epochs, a.lr, seed=r)
        res = evaluate(lambda w, s: MASPPolicy.from_nets(w, nets, seed=s))
        save_weights(out / f"round{r}.pt", nets, "mpe-5")
        print(json.dumps({"round": r, "beta": beta, "states": int(data["action"].shape[0]), "loss": round(loss, 4),
                          **res, "seconds": round(time.perf_counter() - start)}), flush=True)


if __name__ == "__main__":
    main()
