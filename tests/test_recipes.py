"""Recipes as data (:mod:`masp_lite.recipes`): every stage accepted by ``train``, run by name, resumed."""
import json

import pytest

from masp_lite.cli import main
from masp_lite.envs import get_scenario
from masp_lite.policies import learned_methods
from masp_lite.recipes import RECIPES, Recipe, Stage, get_recipe, run_recipe, stage_config


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_every_stage_is_accepted_by_train_and_starts_from_an_earlier_one(name):
    recipe = RECIPES[name]
    seen = []
    for stage in recipe.stages:
        method, cfg, overrides = stage_config(recipe, stage)
        assert method in learned_methods(get_scenario(stage.scenario).kind)
        assert cfg.run.updates == stage.iterations and cfg.run.num_envs == stage.worlds
        assert stage.start is None or stage.start in seen, f"{stage.name} starts from a later or unknown stage"
        assert stage.name not in seen
        seen.append(stage.name)
        assert recipe.chain(stage.name)[-1] == stage and recipe.chain(stage.name)[0].start is None


def test_every_kept_weights_name_belongs_to_one_stage():
    keeps = [s.keep for r in RECIPES.values() for s in r.stages if s.keep]
    assert len(keeps) == len(set(keeps))
    assert {"mpe-5", "mpe-20", "drone-5", "drone-20"} <= set(keeps)  # the shipped MASP (mpe-50: mpe-20's, zero-shot)


def test_a_recipe_may_only_change_what_it_does_not_train_with():
    recipe = get_recipe("masp")
    _, cfg, _ = stage_config(recipe, recipe.stage("mpe-20-both"), ["eval_every=7"])
    assert cfg.run.eval_every == 7 and cfg.ppo.lr == 2e-4 and cfg.reward.gm_reference == "squared"
    with pytest.raises(ValueError, match="would change the recipe"):
        stage_config(recipe, recipe.stage("mpe-20-both"), ["lr=0.1"])


def test_unknown_recipe_or_stage_is_one_clear_error_listing_the_known_ones(tmp_path, capsys):
    assert main(["train", "--recipe", "no-such", "--out", str(tmp_path / "r")]) != 0
    err = capsys.readouterr().err
    assert "unknown recipe 'no-such'" in err and "'masp'" in err and "'mappo-drone'" in err
    assert main(["train", "--recipe", "masp", "--stage", "mpe-7", "--out", str(tmp_path / "r")]) != 0
    err = capsys.readouterr().err
    assert "no stage 'mpe-7'" in err and "'mpe-20-scratch'" in err
    assert main(["train", "--recipe", "masp", "--scenario", "mpe-5", "--out", str(tmp_path / "r")]) != 0
    assert "--scenario come from the recipe" in capsys.readouterr().err
    assert main(["train", "--stage", "mpe-20"]) != 0
    assert "expected --recipe" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def _tiny() -> Recipe:
    budget = {"eval_every": 0, "eval_episodes": 2, "checkpoint_every": 1, "ppo_epochs": 1, "gm_ppo_epochs": 1}
    return Recipe("tiny", "masp", (Stage("first", "mpe-5", 2, 2, budget),
                                   Stage("second", "mpe-5", 1, 2, {**budget, "train_executor": False}, "first",
                                         keep="tiny/mpe-5")))


def test_a_recipe_trains_its_stages_in_turn_skips_finished_ones_and_runs_one_by_name(tmp_path):
    recipe, said = _tiny(), []
    with pytest.raises(ValueError, match="starts from stage first, not trained"):
        run_recipe(recipe, 0, tmp_path / "a", stage="second", progress=False, say=said.append)
    m = run_recipe(recipe, 0, tmp_path / "a", progress=False, say=said.append)
    assert m["iterations"] == 1 and m["init"] == str(tmp_path / "a" / "first" / "weights.pt")
    assert [json.loads((tmp_path / "a" / s / "manifest.json").read_text())["seed"] for s in ("first", "second")] \
        == [0, 0]
    said.clear()
    run_recipe(recipe, 0, tmp_path / "a", progress=False, say=said.append)  # again: nothing trains
    assert all("is done" in s for s in said) and len(said) == 2
    # one stage by name, from the other run's first stage: the same weights as the whole recipe
    again = run_recipe(recipe, 0, tmp_path / "b", stage="second", init=tmp_path / "a" / "first" / "weights.pt",
                       progress=False, say=said.append)
    assert again["weights_sha256"] == m["weights_sha256"]
    assert not (tmp_path / "b" / "first").exists()
