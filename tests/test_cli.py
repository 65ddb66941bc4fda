"""The commands run in-process through the CLI dispatcher; the README and Jupyter set-up they document."""
import json
import logging
import re
from pathlib import Path

import pytest

from masp_lite.__main__ import main


def test_evaluate_writes_json(tmp_path, capsys):
    out = tmp_path / "res" / "h.json"
    rc = main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--episodes", "2",
               "--seeds", "0", "1", "--set", "horizon=6", "--set", "global_step=2", "--json", str(out)])
    assert rc == 0
    rec = json.loads(out.read_text())
    assert {k: rec[k] for k in ("method", "scenario", "seeds", "episodes_per_seed")} == {
        "method": "h-greedy", "scenario": "mpe-5", "seeds": [0, 1], "episodes_per_seed": 2}
    for key in ("sr", "cr", "decision_ms", "steps"):
        assert set(rec[key]) == {"mean", "std"}
    assert 0.0 <= rec["sr"]["mean"] <= 1.0 and rec["cr"]["mean"] >= 0.0
    assert rec["overrides"] == {"horizon": 6} and rec["method_options"] == {"global_step": 2}
    table = capsys.readouterr().out
    assert "h-greedy" in table and "mpe-5" in table


def test_same_seed_same_numbers(tmp_path):
    paths = [tmp_path / "a.json", tmp_path / "b.json"]
    for p in paths:
        assert main(["evaluate", "--method", "random", "--scenario", "mpe-5", "--episodes", "3",
                     "--seeds", "4", "--set", "horizon=5", "--json", str(p)]) == 0
    a, b = (json.loads(p.read_text()) for p in paths)
    assert a["sr"] == b["sr"] and a["cr"] == b["cr"] and a["steps"] == b["steps"]


def test_bad_input_is_one_clear_error(capsys):
    assert main(["evaluate", "--method", "nope", "--scenario", "mpe-5"]) == 2
    err = capsys.readouterr().err
    assert "unknown method 'nope'" in err and "h-greedy" in err and "random" in err
    assert "Traceback" not in err
    assert main(["evaluate", "--method", "random", "--scenario", "mpe-7"]) == 2
    assert "unknown scenario 'mpe-7'" in capsys.readouterr().err
    assert main(["evaluate", "--method", "random", "--scenario", "mpe-5", "--set", "speed=3"]) == 2
    err = capsys.readouterr().err
    assert "speed" in err and "num_agents" in err and "seed" in err  # both lists named
    # h-greedy takes **options (drone worlds hand them on) and names its own; both lists show
    assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--set", "speed=3",
                 "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "speed" in err and "global_step" in err and "num_agents" in err
    assert main(["evaluate", "--method", "random", "--scenario", "mpe-5", "--set", "horizon"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    assert main(["evaluate", "--method", "random", "--scenario", "mpe-5", "--set", "horizon=-1",
                 "--episodes", "1"]) == 2
    assert "horizon >= 1" in capsys.readouterr().err


def test_json_path_is_checked_before_the_evaluation(tmp_path, capsys, monkeypatch):
    import masp_lite.cli.evaluate as cli_evaluate

    def never(*args, **kwargs):
        raise AssertionError("evaluate ran although --json cannot be written")

    monkeypatch.setattr(cli_evaluate, "evaluate", never)
    (tmp_path / "a_file").write_text("")
    for bad, words in ((tmp_path / "a_file" / "out.json", "is a file, not a folder"),
                       (tmp_path / "a_file" / "deeper" / "out.json", "is a file, not a folder"),
                       (tmp_path, "is a folder")):
        assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--json", str(bad)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: --json") and words in err and "Traceback" not in err
    monkeypatch.setattr(cli_evaluate.os, "access", lambda path, mode: False)  # a read-only place
    out = tmp_path / "new" / "o.json"
    assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--json", str(out)]) == 2
    assert "is not writable" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()  # nothing created by the check


def test_table_shows_the_set_overrides_and_options(tmp_path, capsys):
    assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--episodes", "1", "--seeds", "0",
                 "--set", "num_agents=3", "--set", "horizon=4", "--set", "power=2", "--format", "text"]) == 0
    row = capsys.readouterr().out.splitlines()[1]
    assert row.startswith("h-greedy (power=2.0)  mpe-5 (horizon=4, num_agents=3)")  # the parsed values
    from masp_lite.evaluation import format_table
    rec = {"method": "masp", "scenario": "mpe-50", "overrides": {"num_agents": 100},
           "method_options": {"checkpoint": str(tmp_path / "runs" / "weights.pt")},
           **{k: {"mean": 1.0, "std": 0.0} for k in ("steps", "sr", "cr", "decision_ms")}}
    cells = lambda line: [c.strip() for c in line.strip("|").split("|")]  # noqa: E731
    assert cells(format_table([rec]).splitlines()[2])[:2] == ["masp (checkpoint=weights.pt)", "mpe-50 (num_agents=100)"]
    plain = {**rec, "overrides": {}, "method_options": {}}
    paper = format_table([rec, plain], layout="paper").splitlines()  # two method columns, two scenarios
    assert cells(paper[0]) == ["Scenario", "Metric", "masp (checkpoint=weights.pt)", "masp"]
    assert [cells(line)[0] for line in paper[2:] if cells(line)[0]] == ["mpe-50 (num_agents=100)", "mpe-50"]


# ------------------------------------------------------------------ README and Jupyter
ROOT = Path(__file__).resolve().parents[1]


def test_readme_and_every_help_say_how_to_run_with_the_course_environment(capsys):
    from masp_lite.cli import COMMANDS, ENVIRONMENT, PYTHON
    readme = (ROOT / "README.md").read_text()
    assert " ".join(ENVIRONMENT.split()) in " ".join(readme.split())
    bare = re.findall(r"(?<![\w/.])python -m [\w.]+", readme)
    assert bare == [], f"README commands that fail outside the course's environment: {bare}"
    block = readme.split("## Command line", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    assert all(line.startswith(f"{PYTHON} -m masp_lite ") for line in block.splitlines())
    for name in COMMANDS:
        with pytest.raises(SystemExit):
            main([name, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert " ".join(ENVIRONMENT.split()) in text, name
        assert re.findall(r"(?<![\w/.])python -m masp_lite \w+ --", text) == [], name  # examples spelt as README


def test_nbgrader_loads_the_course_config_and_it_agrees_with_generate(monkeypatch, tmp_path):
    from nbgrader.apps import NbGrader
    from nbgrader.coursedir import CourseDirectory

    from masp_lite.course import generate

    def load(cwd):
        monkeypatch.chdir(cwd)
        app = NbGrader()
        warnings = []
        handler = logging.Handler(logging.WARNING)
        handler.emit = warnings.append
        app.log.addHandler(handler)
        try:
            app.load_config_file()
        finally:
            app.log.removeHandler(handler)
        return CourseDirectory(config=app.config), [w.getMessage() for w in warnings]

    _, warnings = load(tmp_path)
    assert any("No nbgrader_config.py" in w for w in warnings)  # what nbgrader says without one
    course, warnings = load(ROOT)
    assert warnings == []
    assert Path(course.root) == ROOT
    assert (Path(course.root) / course.source_directory, Path(course.root) / course.release_directory) == (
        ROOT / generate.SOLUTIONS, ROOT / generate.NOTEBOOKS)  # generate_all's default folders, run from the root


def test_usage_lines_name_the_program_that_was_run(capsys):
    """``masp-lite`` (the console command) and ``python -m masp_lite``: each help names its own program."""
    from masp_lite.cli import MODULE_PROG, console
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"], prog="masp-lite")
    assert capsys.readouterr().out.startswith("usage: masp-lite evaluate ")
    with pytest.raises(SystemExit):
        main(["bench", "env", "--help"], prog="masp-lite")
    assert capsys.readouterr().out.startswith("usage: masp-lite bench env ")
    assert main(["--help"]) == 0
    assert capsys.readouterr().out.startswith(f"usage: {MODULE_PROG} COMMAND")
    import sys
    argv = sys.argv
    try:
        sys.argv = ["masp-lite", "--help"]
        assert console() == 0
    finally:
        sys.argv = argv
    assert capsys.readouterr().out.startswith("usage: masp-lite COMMAND")


def test_what_the_readmes_commands_leave_behind_is_ignored():
    """``pip install .`` (``build/``), ``play ... --out drones.html`` / ``episode.gif`` and ``evaluate --json
    out.json``, run at the repository root as the README runs them, leave no untracked file."""
    import shutil
    import subprocess
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    made = ["build/lib/masp_lite/__init__.py", "build/bdist.linux-x86_64/x", "drones.html", "episode.gif",
            "out.json", "masp_lite.egg-info/PKG-INFO"]
    out = subprocess.run(["git", "check-ignore", "--no-index", *made], cwd=ROOT, capture_output=True, text=True)
    assert sorted(out.stdout.split()) == sorted(made)
    kept = ["README.md", "masp_lite/viz/template.html", "results/README.md", "solutions/00_tour.ipynb"]
    out = subprocess.run(["git", "check-ignore", "--no-index", *kept], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.split() == []  # nothing of the project's own
