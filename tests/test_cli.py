"""The commands run in-process through the CLI dispatcher; the README and Jupyter set-up they document."""
import json
import logging
import re
from pathlib import Path

import pytest

from masp_lite.__main__ import main


def test_evaluate_writes_json(tmp_path, capsys):
    out = tmp_path / "h.json"
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
                       (tmp_path / "new" / "out.json", f"the folder '{tmp_path / 'new'}' does not exist"),
                       (tmp_path, "is a folder")):
        assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--json", str(bad)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: --json") and words in err and "Traceback" not in err
    monkeypatch.setattr(cli_evaluate.os, "access", lambda path, mode: False)  # a read-only place
    out = tmp_path / "o.json"
    assert main(["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--json", str(out)]) == 2
    assert "is not writable" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "new").exists()  # nothing created by the check


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


def test_the_readmes_set_up_commands_are_cis_and_keep_torchs_cpu_wheel():
    """The README's course and test commands install as ``.ci/run`` does (the test command is CI's, ``-q``
    aside); its CPU-wheel command takes ``environment.txt``'s torch pin from PyTorch's CPU index; and
    ``environment.txt`` pins, exactly, every requirement ``pyproject.toml`` declares."""
    import tomllib
    readme = (ROOT / "README.md").read_text()
    blocks = [b.strip() for b in re.findall(r"```bash\n(.*?)```", readme, flags=re.S)]
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1].replace(" -q ", " ")
    install = "python3 -m venv .venv && .venv/bin/pip install -r environment.txt -e ."
    assert ci.startswith(install + " && ") and ci in blocks
    course = [b for b in blocks if ".venv/bin/jupyter lab --config=" in b]
    assert len(course) == 1 and course[0].startswith(install + " && ") and "\n" not in course[0]
    env = (ROOT / "environment.txt").read_text()
    assert "#   pip install -r environment.txt -e ." in env  # its own install line is the README's
    pins = dict(line.split("==") for line in env.splitlines() if line and not line.startswith("#"))
    assert all(re.fullmatch(r"[\w.]+", v) for v in pins.values()), pins  # exact versions, no local label
    cpu = f"python3 -m venv .venv && .venv/bin/pip install torch=={pins['torch']} --index-url " \
          "https://download.pytorch.org/whl/cpu"
    assert cpu in blocks and f"`torch=={pins['torch']}`" in readme
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    declared = {re.split(r"[<>=!~\[; ]", r)[0].lower().replace("_", "-") for r in
                [*project["dependencies"], *(r for extra in project["optional-dependencies"].values() for r in extra)]}
    assert declared - {k.lower() for k in pins} == set()


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


@pytest.mark.parametrize("prog", ["masp-lite", "python -m masp_lite"])
def test_an_installed_copys_every_help_names_its_program_and_no_checkout(prog, monkeypatch, capsys):
    """Without a checkout (an installed copy), the help of every command and bench target: the usage line and the
    examples under the name that was run, nothing about a repository root or its ``.venv``
    (``tests/test_installed.py`` runs a few of them from a built wheel)."""
    import contextlib

    import masp_lite.cli as cli
    from masp_lite.bench import TARGETS
    monkeypatch.setattr(cli, "in_checkout", lambda: False)
    for argv in [[], *([c] for c in cli.COMMANDS), *(["bench", t] for t in TARGETS)]:
        with pytest.raises(SystemExit) if argv else contextlib.nullcontext():
            main([*argv, "--help"], prog=prog)
        text = capsys.readouterr().out
        assert text.startswith(f"usage: {prog} {' '.join(argv) or 'COMMAND'}"), text[:200]
        assert ".venv" not in text and "repository root" not in text, (argv, text[-600:])
        examples = text.split("examples:\n", 1)[1].split("\n\n")[0].splitlines() if argv else []
        assert all(line.startswith(f"  {prog} {argv[0]} ") for line in examples), (argv, examples)
        assert examples or not argv, f"{argv}: no examples"


def test_what_the_readmes_commands_leave_behind_is_ignored():
    """``pip install .`` (``build/``), every file or folder the README's commands name (``play ... --out
    drones.html``, ``evaluate --json out.json``, ``train --out runs/...``, ``classroom init classroom --learners
    masp-lite-course``), chapter 00's ``--json results.json`` and the formgrader's database, made at the
    repository root as the README runs them, leave no untracked file."""
    import shutil
    import subprocess
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    commands = "".join(re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S))
    named = re.findall(r"(?:--out|--json|--learners|classroom init) ([\w./-]+)", commands)
    assert {"out.json", "episode.gif", "drones.html", "runs/mpe-20", "classroom", "masp-lite-course"} <= set(named)
    made = ["build/lib/masp_lite/__init__.py", "build/bdist.linux-x86_64/x", "masp_lite.egg-info/PKG-INFO",
            "results.json", "gradebook.db", *dict.fromkeys(n if Path(n).suffix else f"{n}/x" for n in named)]
    out = subprocess.run(["git", "check-ignore", "--no-index", *made], cwd=ROOT, capture_output=True, text=True)
    assert sorted(out.stdout.split()) == sorted(made)
    kept = ["README.md", "masp_lite/viz/template.html", "results/README.md", "solutions/00_tour.ipynb"]
    out = subprocess.run(["git", "check-ignore", "--no-index", *kept], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.split() == []  # nothing of the project's own
