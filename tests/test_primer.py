"""Chapter 04b's pieces (``masp_lite.primer``) and chapter 06's stage on a budget (``masp_lite.budgets``)."""
import pytest
import torch

from masp_lite import primer
from masp_lite.algos import mappo
from masp_lite.budgets import stage_at
from masp_lite.recipes import get_recipe, stage_config


def test_discounted_returns_example_mask_and_gae_with_lambda_one():
    assert primer.discounted_returns(torch.ones(3), 0.5).tolist() == [1.75, 1.5, 1.0]
    ended = primer.discounted_returns(torch.ones(3), 0.5, not_done=torch.tensor([1.0, 0.0, 1.0]))
    assert ended.tolist() == [1.5, 1.0, 1.0]                                 # nothing flows back across the end
    r = torch.randn(6, 4, generator=torch.Generator().manual_seed(0))
    adv, _ = mappo.gae(r, torch.zeros_like(r), torch.zeros(4), 0.9, 1.0)
    torch.testing.assert_close(primer.discounted_returns(r, 0.9), adv)


def test_reinforce_loss_raises_the_probability_of_actions_with_positive_advantage():
    logits = torch.zeros(2, 5, requires_grad=True)
    primer.reinforce_loss(logits, torch.tensor([1, 3]), torch.tensor([2.0, -2.0])).backward()
    assert logits.grad[0, 1] < 0 and logits.grad[1, 3] > 0                # a gradient step raises 1, lowers 3
    scaled = primer.reinforce_loss(torch.randn(4, 5), torch.arange(4), 100 * torch.arange(4.0))
    unscaled = primer.reinforce_loss(torch.randn(4, 5), torch.arange(4), torch.arange(4.0))
    assert scaled.isfinite() and unscaled.isfinite()


def test_every_variant_learns_and_a_bad_name_fails():
    for method in primer.METHODS:
        run = primer.train_policy_gradient(method, iterations=25, num_envs=32, seed=0)
        assert len(run["return"]) == 25
        assert sum(run["return"][-5:]) / 5 > sum(run["return"][:5]) / 5, method   # the return climbs
    with pytest.raises(ValueError, match="expected method in"):
        primer.train_policy_gradient("a2c")


def test_a_stage_at_another_budget_keeps_everything_but_the_budget():
    recipe = get_recipe("masp")
    scenario, method, cfg, overrides = stage_at("masp", "mpe-5", iterations=10, worlds=4)
    _, full, full_overrides = stage_config(recipe, recipe.stage("mpe-5"))
    assert scenario == "mpe-5" and method == "masp" and overrides == full_overrides == {"num_obstacles": 10}
    changed = {k for k, v in cfg.flat().items() if full.flat()[k] != v}
    assert changed == {"updates", "num_envs", "eval_every", "checkpoint_every"}
    assert (cfg.run.updates, cfg.run.num_envs, cfg.run.eval_every) == (10, 4, 5)
    with pytest.raises(ValueError, match=">= 1"):
        stage_at("masp", "mpe-5", iterations=0, worlds=4)
