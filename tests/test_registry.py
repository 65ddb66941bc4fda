"""One method table, one entrance per input: methods, scenario overrides, checkpoints."""
import ast
import dataclasses
from pathlib import Path

import pytest

import masp_lite.weights as weights
from masp_lite.envs import OVERRIDES, Scenario, make
from masp_lite.evaluation import evaluate
from masp_lite.policies import METHODS, get_factory, learned_methods, make_policy, method_names, option_types

POLICIES = Path(__file__).resolve().parents[1] / "masp_lite" / "policies"


def test_every_entry_of_the_table_resolves_and_learned_ones_name_their_weights():
    for name, kinds in METHODS.items():
        assert kinds and set(kinds) <= {"particle", "drone"}, name
        for kind, entry in kinds.items():
            assert callable(get_factory(name, kind)), (name, kind)
            if "nets" in entry:
                assert entry["weights"] == "shipped" or isinstance(entry["weights"], tuple), name
                assert "method" not in option_types(get_factory(name, kind))  # bound by the table, not an option


def test_the_old_tables_are_views_of_the_one_table():
    from masp_lite.policies.drone_masp import DRONE_METHODS
    from masp_lite.policies.masp import ABLATIONS, BASELINES, METHOD_SETTINGS, VARIANTS
    assert VARIANTS == {m: e["nets"] for m, e in learned_methods("particle").items()}
    assert set(ABLATIONS) == {"masp-rg", "gm-mlp", "cae-mlp"}
    assert set(BASELINES) == {"h-mappo", "htamp", "mage-x", "mappo", "darl1n"}
    assert METHOD_SETTINGS["mage-x"]["global_step"] == 1000
    assert DRONE_METHODS == {"masp": "throttle", "masp-velocity": "velocity",
                             **{m: "throttle" for m in ("h-mappo", "htamp", "mage-x", "mappo", "darl1n")}}


def test_no_policy_class_redirects_itself():
    for path in POLICIES.glob("*.py"):
        tree = ast.parse(path.read_text())
        news = [n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == "__new__"]
        assert not news, f"{path.name} defines __new__"
        assert "__new__" not in path.read_text(), path.name


def test_a_world_kind_a_method_lacks_is_one_clear_error():
    w = make("mpe-5", num_envs=1, seed=0)
    with pytest.raises(ValueError, match="masp-velocity: no policy for particle worlds; expected a drone scenario"):
        make_policy("masp-velocity", w)
    assert "masp-velocity" in method_names("drone") and "masp-velocity" not in method_names("particle")


def test_scenario_overrides_are_scenarios_fields():
    assert set(OVERRIDES) == {f.name for f in dataclasses.fields(Scenario)} - {"name", "kind"}
    assert OVERRIDES["team_after"] == int | None and OVERRIDES["world_size"] is float


def test_a_checkpoint_has_one_entrance(tmp_path, capsys):
    from masp_lite.cli import main
    ckpt = weights.default_checkpoint("mpe-5")
    assert main(["evaluate", "--method", "masp", "--scenario", "mpe-5", "--episodes", "1", "--seeds", "0",
                 "--set", f"checkpoint={ckpt}"]) == 2
    assert "expected --checkpoint PATH" in capsys.readouterr().err
    with pytest.raises(ValueError, match="expected one checkpoint"):
        evaluate("masp", "mpe-5", episodes=1, seeds=[0], checkpoint=ckpt, method_options={"checkpoint": "other.pt"})


def test_a_weights_file_is_read_from_disk_once(tmp_path, monkeypatch):
    path = tmp_path / "mpe-5.pt"
    path.write_bytes(weights.default_checkpoint("mpe-5").read_bytes())
    reads = []
    real = weights.read_bounded  # the one bounded reader every weights file goes through
    monkeypatch.setattr(weights, "read_bounded", lambda p, *a, **k: reads.append(Path(p)) or real(p, *a, **k))
    rec = evaluate("masp", "mpe-5", episodes=2, seeds=[0, 1, 2], checkpoint=path)
    assert rec["checkpoint_sha256"] == weights.sha256(path)
    assert [p for p in reads if p.name == "mpe-5.pt"] == [path.resolve()]  # three seeds, its hash: one read
