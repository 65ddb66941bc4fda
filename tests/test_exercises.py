"""Exercises teach rather than leak: no chapter shows an exercise's reference before the exercise,
and every graded exercise refuses an answer that only calls the library's version.

* The reference of an exercise is what its graded cell's ``course.check(mine, REFERENCE, ...,
  hide=[...])`` names. Before the exercise's heading, no ``course.show(X)`` may show it — or
  anything whose source contains its source (a class holding the method, say).
* Every graded exercise of every chapter, answered by calling the library (:data:`CHEATS`, one
  per solution cell), fails its check with "unavailable" and its graded cell raises
  ``ExerciseNotPassed`` — what ``nbgrader autograde`` scores zero.
"""
import ast
import inspect
import os
import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

from masp_lite.course import authoring

ROOT = Path(__file__).resolve().parents[1]
SOLUTIONS = sorted((ROOT / "solutions").glob("*.ipynb"))


def _grade(cell):
    return cell.metadata.get("nbgrader", {})


def _calls(source, dotted):
    """The ``ast.Call`` nodes of ``source`` calling ``dotted`` (e.g. 'course.show')."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and ast.unparse(n.func) == dotted]


def _imports(nb):
    """A namespace holding every name the notebook's code cells import."""
    ns = {}
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        try:
            tree = ast.parse(cell.source)
        except SyntaxError:
            continue
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                try:
                    exec(compile(ast.Module([node], []), "<imports>", "exec"), ns)
                except Exception:  # noqa: BLE001 - an optional import (e.g. mpe2) is no reference
                    pass
    return ns


def _resolve(expr, ns):
    try:
        return eval(expr, dict(ns))
    except Exception:  # noqa: BLE001 - a notebook-defined wrapper: its library part is in hide=[...]
        return None


def _source(obj):
    try:
        return inspect.getsource(obj)
    except (TypeError, OSError):
        return None


def leaks(nb):
    """``(exercise heading, shown expression, reference expression)`` for every reference shown too early."""
    ns = _imports(nb)
    found = []
    heading_at = None
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown" and re.match(r"### Exercise \d+", cell.source):
            heading_at = i
        if not _grade(cell).get("grade"):
            continue
        for call in _calls(cell.source, "course.check"):
            refs = [ast.unparse(call.args[1])] if len(call.args) > 1 else []
            for kw in call.keywords:
                if kw.arg == "hide" and isinstance(kw.value, (ast.List, ast.Tuple)):
                    refs += [ast.unparse(e) for e in kw.value.elts]
            targets = [(r, _resolve(r, ns)) for r in refs]
            for before in nb.cells[:heading_at]:
                if before.cell_type != "code":
                    continue
                for show in _calls(before.source, "course.show"):
                    shown_expr = ast.unparse(show.args[0])
                    shown = _resolve(shown_expr, ns)
                    shown_src = _source(shown) if shown is not None else None
                    for ref, obj in targets:
                        same = shown_expr == ref or (obj is not None and shown is obj)
                        inside = obj is not None and shown_src and _source(obj) and _source(obj) in shown_src
                        if same or inside:
                            found.append((nb.cells[heading_at].source.splitlines()[0], shown_expr, ref))
    return found


@pytest.mark.parametrize("path", SOLUTIONS, ids=[p.stem for p in SOLUTIONS])
def test_no_reference_is_shown_before_its_exercise(path):
    assert leaks(nbformat.read(path, as_version=4)) == []


def test_a_reference_shown_before_its_exercise_is_found():
    A = authoring
    nb = A.notebook([
        A.markdown("## Section 1: Attention (~5 min)"),
        A.code("import masp_lite.course as course\nfrom masp_lite.nets import encoders"),
        A.code("course.show(encoders.s_inter)"),
        A.code("course.show(encoders.SelfEncoder)"),
        A.code("course.show(encoders.CrossEncoder)"),
        A.markdown("### Exercise 1: S_inter"),
        A.solution("def my_s_inter(q, k, mask=None):\n    ### BEGIN SOLUTION\n    pass\n    ### END SOLUTION", "s"),
        A.graded("f = course.check(my_s_inter, encoders.s_inter, inputs=[], name='s')", "check_s"),
        A.markdown("### Exercise 2: scores"),
        A.solution("def my_scores(c, a, t, d):\n    ### BEGIN SOLUTION\n    pass\n    ### END SOLUTION", "c"),
        A.graded("f = course.check(my_scores, library_scores, inputs=[], name='c',\n"
                 "                 hide=[encoders.CrossEncoder.scores])", "check_c"),
    ])
    assert leaks(nb) == [("### Exercise 1: S_inter", "encoders.s_inter", "encoders.s_inter"),  # the reference
                         ("### Exercise 2: scores", "encoders.CrossEncoder",                 # its class
                          "encoders.CrossEncoder.scores")]


# ------------------------------------------------------------------ call-the-library answers
#: For every solution cell (by grade_id), a body that only calls the library's version.
CHEATS = {
    "quick_evaluate": 'record = ev.evaluate(method, scenario, episodes=episodes, seeds=(seed,))\n'
                      'return record["sr"]["mean"], record["steps"]["mean"], record["cr"]["mean"]',
    "physics_step": 'w = make("mpe-5", num_envs=pos.shape[0], num_agents=pos.shape[1], num_obstacles=0,\n'
                    '         world_size=20.0, seed=0, integration=integration)\n'
                    'w.reset(options={"agent_pos": pos, "agent_vel": vel})\n'
                    'obs, _ = w.step(actions)\n'
                    'return obs["agent_pos"], obs["agent_vel"]',
    "contact_force": "return particle.contact_force(delta, dist, dist_min)",
    "episode_metrics": "return ev.success_rate(log), ev.steps(log), ev.collision_rate(log)",
    "hungarian": "return assignment.hungarian(agent_pos, goal_pos, agent_mask, goal_mask)",
    "choose_action": "return reference.velocity_to_action(vel, desired_vel)",
    "my_bottleneck": "return team._bottleneck_one(dist)",
    "s_inter": "return encoders.s_inter(query, key, mask)",
    "self_encoder": "return encoder(x, mask)",
    "cross_scores": "return torch.softmax(cross(y_a, y_t, dist), dim=-1)",
    "goal_matcher_reward": "return rewards.goal_matcher_reward(agent_pos, goal_pos, goals, alive)",
    "group_division": "return fusion.group_division(perm, group_size)",
    "gcn_layer": "return fusion.gcn_layer(h, adj, linear)",
    "executor_reward": "return rewards.executor_reward(agent_pos, goal_pos, agent_collisions, alive, reach,\n"
                       "                               world_size, alpha, beta, gamma)",
    "gae": "return mappo.gae(rewards, values, next_value, gamma, lam, not_done)",
    "clipped_surrogate": "return mappo.clipped_surrogate(logp, old_logp, adv, clip, mask)",
    "value_norm": "norm = mappo.ValueNorm(beta=beta)\nfor batch in batches:\n    norm.update(batch)\n"
                  "return norm.normalize(x)",
    "value_loss": "return mappo.value_loss(values, old_values, targets, clip, delta, mask)",
    "discounted_returns": "return primer.discounted_returns(rewards, gamma, not_done)",
    "reinforce_loss": "return primer.reinforce_loss(logits, actions, advantages)",
    "train_stage": "return train_stage_at(recipe_name, stage_name, seed, out, iterations, worlds, init=init)",
    "evaluate_nets": 'numbers = evaluate_nets(nets, scenario, episodes=episodes, seed=seed)\n'
                     'return {key: numbers[key] for key in ("sr", "steps", "cr")}',
    "orca_halfplane": "return orca.orca_halfplanes(rel_pos, rel_vel, vel, combined_radius, responsibility,\n"
                      "                           time_horizon, time_step)",
    "rewire_step": "better = rrt_star.rewire(nodes, cost, parent, new, near, free)\nreturn better, cost, parent",
    "extract_route": "return voronoi.route(predecessors, source, target)",
    "mixing_matrix": "return geometric.mixing_matrix(arm_length, rotor_angles, directions, yaw_ratio)",
    "position_loop": "return geometric.position_loop(pos, vel, target_pos, target_vel, target_acc, kx, kv, max_speed)",
    "coverage": "alive = torch.ones(agent_pos.shape[:2], dtype=torch.bool)\n"
                "return coverage_reward(agent_pos, landmark_pos, agent_collisions, alive, reach, world_size)",
    "nearest_view": "idx, ok = nearest_others(pair, alive, count)\n"
                    "rows = torch.gather(pair, 2, idx.unsqueeze(-1).expand(*idx.shape, pair.shape[-1]))\n"
                    "return rows.flatten(2)",
    "gm_mlp_input": "B, N, _ = agent_pos.shape\n"
                    "agents = (agent_pos * alive.unsqueeze(-1))[:, ablations.agent_first(N)].reshape(B, N, -1)\n"
                    "return torch.cat([agents, goal_pos.reshape(B, 1, -1).expand(B, N, -1)], dim=-1)",
    "group_count": "return fusion.group_division(torch.arange(num_agents)[None], group_size).shape[2]",
    "gaussian_log_prob": "return gaussian_log_prob(mean, log_std, actions)",
    "drone_reward": '_, cfg, overrides = method_config(None, ["num_envs=1", f"distance_coef={beta}"], scenario)\n'
                    "trainer = DroneMASPTrainer(scenario, cfg, overrides=overrides)\n"
                    'return trainer.executor_reward(obs, goals, {"agent_collisions": collisions}, alive, t)',
    "steps_cut": "return _cut(base_steps, masp_steps)",
    "episode_entries": "env = ParticleTorchRLEnv(scenario, num_envs=actions.shape[0], seed=seed)\n"
                       "td = env.rollout(actions.shape[1])\n"
                       'return {k: td["next", "episode", k] for k in METRICS}',
}


def _cheat(source, body):
    """``source`` with the text between its solution markers replaced by ``body``."""
    m = re.search(r"^( *)### BEGIN SOLUTION\n.*?^ *### END SOLUTION", source, flags=re.S | re.M)
    assert m, source
    indent = m.group(1)
    return source[:m.start()] + "\n".join(indent + line for line in body.splitlines()) + source[m.end():]


def test_every_solution_cell_has_a_cheat():
    ids = {_grade(c)["grade_id"] for p in SOLUTIONS for c in nbformat.read(p, as_version=4).cells
           if _grade(c).get("solution")}
    assert ids == set(CHEATS)


@pytest.mark.slow
@pytest.mark.parametrize("path", SOLUTIONS, ids=[p.stem for p in SOLUTIONS])
def test_every_graded_exercise_refuses_a_call_to_the_library(path, tmp_path, monkeypatch):
    nb = nbformat.read(path, as_version=4)
    graded = [i for i, c in enumerate(nb.cells) if _grade(c).get("grade")]
    nb.cells = nb.cells[:graded[-1] + 1]            # the chapter up to its last graded cell
    for cell in nb.cells:
        if _grade(cell).get("solution"):
            cell.source = _cheat(cell.source, CHEATS[_grade(cell)["grade_id"]])
    monkeypatch.setenv("MASP_LITE_FAST", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    NotebookClient(nb, timeout=600, allow_errors=True, kernel_name="python3",
                   resources={"metadata": {"path": str(ROOT / "solutions")}}).execute()
    for i in graded:
        cell = nb.cells[i]
        errors = [o for o in cell.outputs if o.output_type == "error"]
        text = "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream")
        gid = _grade(cell)["grade_id"]
        assert errors and errors[0].ename == "ExerciseNotPassed", f"{gid}: {text} {errors}"
        assert "unavailable" in text, f"{gid}: the check did not say the library was unavailable: {text}"
        assert len(errors[0].traceback) == 1, f"{gid}: expected a one-line failure, got {errors[0].traceback}"
    # cells before the graded ones ran without errors (the chapter itself is fine with these answers)
    broken = [(i, o.ename) for i, c in enumerate(nb.cells) if c.cell_type == "code" and i not in graded
              for o in c.outputs if o.output_type == "error"]
    assert broken == [], broken
    assert os.environ["MASP_LITE_FAST"] == "1"


def test_every_reference_answer_is_at_least_three_lines_of_code():
    """An exercise asks for a step the learner reasons out, not one broadcast or one formula."""
    short = {}
    for path in SOLUTIONS:
        for cell in nbformat.read(path, as_version=4).cells:
            if not _grade(cell).get("solution"):
                continue
            body = cell.source.split("### BEGIN SOLUTION")[1].split("### END SOLUTION")[0]
            lines = [line for line in body.splitlines() if line.strip() and not line.strip().startswith("#")]
            if len(lines) < 3:
                short[_grade(cell)["grade_id"]] = (path.name, len(lines))
    assert short == {}, f"answers shorter than three lines of code (grade id: notebook, lines): {short}"
