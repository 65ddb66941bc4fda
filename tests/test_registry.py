"""One method table, one entrance per input: methods, scenario overrides, checkpoints."""
import ast
import dataclasses
from pathlib import Path

import pytest

import masp_lite.files as files
import masp_lite.weights as weights
from masp_lite.envs import OVERRIDES, Scenario, make
from masp_lite.evaluation import evaluate
from masp_lite.files import sha256
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
    assert "--checkpoint PATH on the command line" in capsys.readouterr().err
    for options in ({"checkpoint": "other.pt"}, {"checkpoint": str(ckpt)}):  # another file, or the same one twice
        with pytest.raises(ValueError, match="method option checkpoint: expected the weights file as evaluate's "
                                             "checkpoint=PATH"):
            evaluate("masp", "mpe-5", episodes=1, seeds=[0], checkpoint=ckpt, method_options=options)
    with pytest.raises(ValueError, match="method option checkpoint"):  # a record's options, passed back as they are
        evaluate("masp", "mpe-5", episodes=1, seeds=[0], method_options={"checkpoint": str(ckpt)})
    for bad in (3, True, "", b"w.pt"):
        with pytest.raises(ValueError, match="checkpoint: expected the path of a weights file"):
            evaluate("masp", "mpe-5", episodes=1, seeds=[0], checkpoint=bad)
    rec = evaluate("masp", "mpe-5", episodes=1, seeds=[0], checkpoint=ckpt)  # a Path: kept as a str, with its hash
    assert rec["method_options"] == {"checkpoint": str(ckpt)} and rec["checkpoint_sha256"] == sha256(ckpt)


def test_a_weights_file_is_read_from_disk_once(tmp_path, monkeypatch):
    path = tmp_path / "mpe-5.pt"
    path.write_bytes(weights.default_checkpoint("mpe-5").read_bytes())
    reads = []
    real = files.read_bounded  # the one bounded reader every weights file goes through
    monkeypatch.setattr(files, "read_bounded", lambda p, *a, **k: reads.append(Path(p)) or real(p, *a, **k))
    rec = evaluate("masp", "mpe-5", episodes=2, seeds=[0, 1, 2], checkpoint=path)
    assert rec["checkpoint_sha256"] == files.sha256(path)
    assert [p for p in reads if p.name == "mpe-5.pt"] == [path.resolve()]  # three seeds, its hash: one read


class _CountingPresets(dict):
    """The preset table, counting how often a preset is looked up by name."""

    lookups = 0

    def __getitem__(self, name):
        type(self).lookups += 1
        return super().__getitem__(name)


@pytest.mark.parametrize("method", ["h-greedy", "masp"])
def test_a_scenario_name_is_looked_up_once_per_evaluate_and_per_train(method, tmp_path, monkeypatch):
    """evaluate (three seeds) and train (a periodic and a final evaluation, weights saved) each turn the name into
    a Scenario once and pass that on."""
    from masp_lite.envs import scenarios
    from masp_lite.training import method_config, train
    monkeypatch.setattr(scenarios, "SCENARIOS", _CountingPresets(scenarios.SCENARIOS))
    monkeypatch.setattr(_CountingPresets, "lookups", 0)
    evaluate(method, "mpe-5", episodes=2, seeds=[0, 1, 2], overrides={"horizon": 5})
    assert _CountingPresets.lookups == 1
    if method == "masp":
        _, cfg, _ = method_config("masp", ["num_envs=2", "updates=1", "eval_every=1", "eval_episodes=2", "width=8",
                                           "ppo_epochs=1", "gm_ppo_epochs=1"])
        monkeypatch.setattr(_CountingPresets, "lookups", 0)
        train("mpe-5", cfg, tmp_path / "run", overrides={"horizon": 6}, progress=False)
        assert _CountingPresets.lookups == 1
