"""The evaluate command, run in-process through the CLI dispatcher."""
import json

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
