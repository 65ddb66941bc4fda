"""``reproduce``: the paper's tables from records, ours beside the paper's, never mixing worlds."""
import json
from pathlib import Path

import pytest

from masp_lite.cli import main
from masp_lite.envs import get_scenario
from masp_lite.reproduction import reproduce as rp


def _rec(method, scenario, steps=10.0, world=None, **extra):
    return {"method": method, "scenario": scenario, "world": world or get_scenario(scenario).world,
            "seeds": [0], "episodes_per_seed": 1, "sr": {"mean": 1.0, "std": 0.0},
            "steps": {"mean": steps, "std": 1.0}, "cr": {"mean": 0.1, "std": 0.0},
            "decision_ms": {"mean": 1.0, "std": 0.0}, **extra}


def test_tables_from_the_committed_records_show_ours_and_the_papers():
    records = rp.load_records()
    text = rp.render(rp.build("mpe", records), "text")
    masp20 = rp.pick(records, "masp", "mpe-20")
    assert f"{masp20['steps']['mean']:.2f} ({masp20['steps']['std']:.2f})" in text
    assert "25.61 (2.10)" in text and "47.46 (5.93)" in text       # the paper's MASP, N = 20 and 50
    assert "world: integration=" in text
    latex = rp.render(rp.build("mpe", records, latex=True), "latex")
    assert r"$\backslash$" in latex and r"\scriptsize{(2.10)}" in latex  # the paper's "\" and its stds
    for name in rp.TABLES:
        assert rp.render(rp.build(name, records), "markdown").count("\n") > 3


def test_a_record_from_another_world_is_never_used():
    other = {"integration": "velocity_first", "landmark_spawn": "central"}
    if get_scenario("mpe-20").world == other:
        other = {"integration": "mpe2", "landmark_spawn": "whole"}
    records = [_rec("h-greedy", "mpe-20", 12.34, world=other)]
    assert rp.pick(records, "h-greedy", "mpe-20") is None
    assert "12.34" not in rp.render(rp.build("mpe", records), "text")
    records.append(_rec("h-greedy", "mpe-20", 23.45))
    assert "23.45 (1.00)" in rp.render(rp.build("mpe", records), "text")


def test_options_and_duplicates():
    records = [_rec("masp", "mpe-5", 9.0, method_options={"decode": "hungarian"})]
    assert rp.pick(records, "masp", "mpe-5") is None              # a diagnostic, not the method
    records += [_rec("masp", "mpe-5", 8.0), _rec("masp", "mpe-5", 8.5)]
    with pytest.raises(ValueError, match="expected one"):
        rp.pick(records, "masp", "mpe-5")
    with pytest.raises(ValueError, match="unknown table"):
        rp.build("nope", [])


def test_evaluate_records_asks_for_every_registered_method(monkeypatch):
    calls = []
    monkeypatch.setattr(rp, "evaluate", lambda m, sc, **kw: calls.append((m, sc, kw["episodes"])) or _rec(m, sc))
    records = rp.evaluate_records("mpe-varying", episodes=4)
    assert {c[0] for c in calls} >= {"h-orca", "h-rrtstar", "h-voronoi", "masp", "h-bottleneck"}
    assert "mappo" not in {c[0] for c in calls} and {c[2] for c in calls} == {4}
    assert len(records) == len(calls)


def test_evaluate_records_runs_kept_weights_only_where_they_fly(monkeypatch):
    calls = []
    monkeypatch.setattr(rp, "evaluate", lambda m, sc, **kw: calls.append((m, sc, kw.get("checkpoint"))) or _rec(m, sc))
    rp.evaluate_records("faithful", episodes=1)
    kept = {sc for m, sc, checkpoint in calls if checkpoint}
    assert kept == {"mpe-20", "mpe-50", "mpe-20to10", "mpe-50to20"}          # the mpe-20 weights: not on mpe-5
    assert {sc for m, sc, checkpoint in calls if not checkpoint} == {"mpe-5", "mpe-20", "mpe-50", "mpe-20to10",
                                                                     "mpe-50to20"}


def test_cli(tmp_path, capsys):
    assert main(["reproduce", "--table", "mpe-varying", "--format", "text"]) == 0
    assert "40.68 (3.37)" in capsys.readouterr().out
    (tmp_path / "r.json").write_text(json.dumps(_rec("masp", "mpe-20to10", 21.0)))
    assert main(["reproduce", "--table", "mpe-varying", "--records", str(tmp_path)]) == 0
    assert "21.00 (1.00)" in capsys.readouterr().out
    assert main(["reproduce", "--records", str(tmp_path / "missing")]) == 2


def test_training_seeds_are_pooled_exactly():
    a = _rec("masp", "mpe-20", 20.0)
    b = _rec("masp", "mpe-20", 22.0, method_options={"checkpoint": "results/training/mpe-20-seed1.pt"})
    c = _rec("masp", "mpe-20", 30.0, method_options={"checkpoint": "results/training/mpe-50-seed2.pt"})
    assert [rp.training_seed(r) for r in (a, b, c)] == [0, 1, None]   # seed 2 of another preset: not pooled
    got = rp.pick([a, b, c], "masp", "mpe-20")
    assert got["training_seeds"] == [0, 1] and got["steps"]["mean"] == 21.0
    # two episodes per record, steps (19, 21) and (21, 23): population std of all four is sqrt(2)
    assert got["steps"]["std"] == pytest.approx(2 ** 0.5)
    table = rp.build("mpe", [a, b])
    assert "mean over training seeds 0, 1: MASP (mpe-20)" in rp.render(table, "text")
    with pytest.raises(ValueError, match="expected one"):
        rp.pick([a, b, dict(b)], "masp", "mpe-20")
    unsolved = {**b, "steps": {"mean": None, "std": None}}  # every episode scored the horizon, 45
    assert rp.pool([a, unsolved])["steps"]["mean"] == (20.0 + 45) / 2


def test_another_recipes_seeds_are_kept_apart():
    shipped = _rec("masp", "mpe-50", 50.0)
    f0, f1 = (_rec("masp", "mpe-50", x, method_options={"checkpoint": f"results/training/faithful/mpe-20-seed{k}.pt"})
              for k, x in ((0, 60.0), (1, 64.0)))
    assert [rp.training_seed(r) for r in (shipped, f0, f1)] == [0, None, None]    # not the shipped recipe's
    assert [rp.training_seed(r, rp.FAITHFUL) for r in (shipped, f0, f1)] == [None, 0, 1]
    assert rp.pick([shipped, f0, f1], "masp", "mpe-50")["steps"]["mean"] == 50.0
    assert rp.pick([shipped, f0], "masp", "mpe-50", rp.FAITHFUL)["training_seeds"] == [0]   # one seed: still named
    text = rp.render(rp.build("faithful", [shipped, f0, f1]), "text")
    assert "50.00 (1.00)" in text and "62.00 (" in text
    assert "mean over training seeds 0, 1: MASP (eq. 1 as written) (mpe-50)" in text
    assert rp.pick([shipped], "masp", "mpe-50", rp.FAITHFUL) is None


def test_ablation_tables_put_each_variants_seeds_in_its_column():
    def kept(method, folder, steps, seed=0):
        return _rec(method, "mpe-20", steps,
                    method_options={"checkpoint": f"results/training/{folder}/mpe-20-seed{seed}.pt"})
    records = [kept("masp-rg", "masp-rg", 31.0), kept("masp", "faithful", 25.0), kept("masp", "faithful", 27.0, 1),
               kept("masp", "group-size-2", 29.0), _rec("masp", "mpe-20", 20.0)]   # the shipped one: in none
    ab = rp.build("ab", records)
    # matched seeds: the variant has seed 0 only, so MASP's column is its seed 0 (25), not the mean of 0 and 1
    assert ab.rows[0][3:] == ["31.00 (1.00)", "—", "—", "25.00 (1.00)"] and ab.rows[1][3:7] == \
        ["35.91 (2.73)", "\\", "28.25 (3.21)", "24.41 (2.66)"]
    assert rp.build("groupsize", records).rows[0][3:] == ["29.00 (1.00)", "25.00 (1.00)", "—"]
    assert rp.build("globalsteps", records).rows[0][3:] == ["—", "26.00 (1.41)", "—"]   # nothing to match: both seeds
    assert rp.build("globalsteps", records).rows[1][3:] == ["24.23 (2.11)", "24.41 (2.66)", "29.59 (2.43)"]
    claims = {r[0]: r[1:] for r in rp.build("ablation-claims", records).rows}
    assert claims["MASP w. RG needs more Steps than MASP"] == \
        ["35.91 vs 24.41 (32.0 % fewer)", "31.00 vs 25.00 (19.4 % fewer)", "yes"]
    assert claims["N_g = 2 needs more Steps than N_g = 3"][2] == "yes"
    assert claims["GM w.o. Graph fails (SR < 0.5)"] == ["SR 0.04", "—", "—"]


def test_claims_are_computed_from_the_records():
    records = [_rec("masp", "mpe-50", 40.0), _rec("h-orca", "mpe-50", 60.0), _rec("h-rrtstar", "mpe-50", 50.0),
               _rec("h-voronoi", "mpe-50", 48.0), _rec("h-greedy", "mpe-50", 39.0)]
    rows = {(r[0], r[1]): r for r in rp.build("claims", records).rows}
    assert rows[("MASP fewer Steps than every (H) planner", "mpe-50")][3:] == ["40.00 vs (H)Voronoi 48.00", "yes"]
    assert rows[("MASP fewer Steps than h-greedy (ours only)", "mpe-50")][4] == "no"
    cut = rows[("MASP ≥ 19.12 % fewer Steps than (H)RRT* (and the best (H))", "mpe-50")]
    assert cut[3] == "20.0 % vs (H)RRT*, 16.7 % vs best" and cut[4] == "no"   # 19.12 % only against (H)RRT*
    assert rows[("MASP SR ≥ 0.99", "mpe-50")][4] == "yes" and rows[("MASP SR ≥ 0.99", "mpe-5")][4] == "—"
    assert rows[("MASP the lowest CR", "mpe-50")][4] == "no"                 # 0.1 everywhere: a tie is not lower


def test_rl_claims_are_computed_from_the_kept_seeds():
    def kept(method, steps, sr):
        rec = _rec(method, "mpe-50", steps, method_options={"checkpoint": f"results/training/{method}/mpe-50-seed0.pt"})
        return {**rec, "sr": {"mean": sr, "std": 0.0}}
    failing = [kept("mappo", None, 0.02), kept("darl1n", None, 0.4), kept("htamp", None, 0.01),
               kept("mage-x", None, 0.3)]
    records = [_rec("masp", "mpe-50", 40.0), _rec("h-orca", "mpe-50", 60.0), kept("h-mappo", 44.0, 1.0), *failing]
    rows = {(r[0], r[1]): r for r in rp.build("claims", records).rows}
    assert rows[("Only (H)MAPPO keeps SR ≥ 0.99 among the RL baselines", "mpe-50")][4] == "yes"
    assert rows[("No RL baseline but (H)MAPPO completes an episode", "mpe-50")][3:] == \
        ["MAPPO \\, DARL1N \\, HTAMP \\, MAGE-X \\", "yes"]
    assert rows[("MASP fewer Steps than every RL baseline", "mpe-50")][3:] == ["40.00 vs (H)MAPPO 44.00", "yes"]
    assert rows[("MASP ≥ 8.52 % fewer Steps than (H)MAPPO", "mpe-50")][3:] == ["9.1 %", "yes"]
    assert rows[("MASP ≥ 21.76 % fewer Steps than (H)ORCA", "mpe-50")][3:] == ["33.3 %", "yes"]
    assert rows[("DARL1N fails (SR < 0.5)", "mpe-50")][3:] == ["0.40", "yes"]
    # MAGE-X solving at N = 50 breaks two claims; a missing baseline leaves the team-wide ones open
    records[-1] = kept("mage-x", 50.0, 1.0)
    rows = {(r[0], r[1]): r for r in rp.build("claims", records).rows}
    assert rows[("Only (H)MAPPO keeps SR ≥ 0.99 among the RL baselines", "mpe-50")][4] == "no"
    assert rows[("No RL baseline but (H)MAPPO completes an episode", "mpe-50")][4] == "no"
    assert rows[("MAGE-X fails (SR < 0.5)", "mpe-50")][3:] == ["1.00", "no"]
    rows = {(r[0], r[1]): r for r in rp.build("claims", records[:-1]).rows}
    assert rows[("Only (H)MAPPO keeps SR ≥ 0.99 among the RL baselines", "mpe-50")][3:] == ["—", "—"]


def test_the_drone_tables_put_ours_beside_the_papers():
    records = [_rec("h-orca", "drone-20", 401.5), _rec("h-voronoi", "drone-20to10", 480.25)]
    text = rp.render(rp.build("omnidrones", records), "text")
    assert "401.50 (1.00)" in text and "315.31 (14.52)" in text and "437.43 (14.24)" in text
    varying = rp.render(rp.build("omnidrones-varying", records), "text")
    assert "480.25 (1.00)" in varying and "426.73 (18.50)" in varying and "h-greedy" in varying


def test_drone_claims_are_computed_from_the_records():
    records = [_rec("masp", "drone-20", 300.0), _rec("h-orca", "drone-20", 420.0), _rec("h-rrtstar", "drone-20", 400.0),
               _rec("h-voronoi", "drone-20", 450.0), _rec("h-orca", "drone-20to10", 280.0),
               _rec("h-rrtstar", "drone-20to10", 290.0)]
    rows = {(r[0], r[1]): r for r in rp.build("drone-claims", records).rows}
    assert rows[("MASP SR ≥ 0.95", "drone-20")][3:] == ["1.000", "yes"]
    assert rows[("MASP SR ≥ 0.99", "drone-5")][3:] == ["—", "—"]
    assert rows[("MASP (velocity) SR ≥ 0.95", "drone-20")][3:] == ["—", "—"]   # the variant: its own rows
    vel = {"checkpoint": "results/training/masp-velocity/drone-20-seed0.pt"}  # a kept training seed
    velocity = {(r[0], r[1]): r for r in rp.build("drone-claims", records + [
        {**_rec("masp-velocity", "drone-20", 350.0, method_options=vel), "sr": {"mean": 0.96, "std": 0.1}}]).rows}
    assert velocity[("MASP (velocity) SR ≥ 0.95", "drone-20")][3:] == ["0.960", "yes"]
    assert velocity[("MASP (velocity) fewer Steps than every (H) planner", "drone-20")][3:] == \
        ["350.00 vs (H)RRT* 400.00", "yes"]
    assert velocity[("MASP SR ≥ 0.95", "drone-20")][3:] == ["1.000", "yes"]              # MASP's rows unchanged
    assert rows[("MASP fewer Steps than every (H) planner", "drone-20")][3:] == ["300.00 vs (H)RRT* 400.00", "yes"]
    cut = rows[("MASP ≥ 27.92 % fewer Steps than the best (H) planner", "drone-20")]
    assert cut[2:] == ["27.9 %", "25.0 %", "no"]                  # (400 - 300) / 400, below the paper's cut
    assert rows[("MASP the lowest CR", "drone-20")][4] == "no"       # 0.1 everywhere: a tie is not lower
    assert rows[("No (H) planner reaches SR 1.00", "drone-20to10")][3:] == ["—", "—"]   # h-voronoi missing
    records.append(_rec("h-voronoi", "drone-20to10", 300.0))
    rows = {(r[0], r[1]): r for r in rp.build("drone-claims", records).rows}
    assert rows[("No (H) planner reaches SR 1.00", "drone-20to10")][3:] == ["(H)ORCA 1.000", "no"]
    assert rows[("Every (H) planner SR > 0.90", "drone-20")][3:] == ["lowest (H)ORCA 1.000", "yes"]
    assert rows[("MASP SR ≥ 0.94 zero-shot", "drone-20to10")][3:] == ["—", "—"]
    five = [_rec("h-orca", "drone-5", 140.0), _rec("h-rrtstar", "drone-5", 150.0),
            {**_rec("h-voronoi", "drone-5", 145.0), "sr": {"mean": 0.85, "std": 0.1}}]
    rows = {(r[0], r[1]): r for r in rp.build("drone-claims", five).rows}
    assert rows[("(H)Voronoi the best (H) planner (Steps)", "drone-5")][3:] == ["(H)ORCA 140.00", "no"]
    assert rows[("Every (H) planner SR > 0.90", "drone-5")][3:] == ["lowest (H)Voronoi 0.850", "no"]


def test_drone_rl_claims_are_computed_from_the_kept_seeds():
    def kept(method, sc, steps, sr, seed=0, cr=0.1):
        rec = _rec(method, sc, steps, method_options={"checkpoint": f"results/training/{method}/{sc}-seed{seed}.pt"})
        return {**rec, "sr": {"mean": sr, "std": 0.0}, "cr": {"mean": cr, "std": 0.0}}
    five = [kept("h-mappo", "drone-5", 180.0, 1.0), kept("mage-x", "drone-5", 200.0, 0.95),
            kept("mappo", "drone-5", 290.0, 0.4), kept("darl1n", "drone-5", 280.0, 0.6),
            kept("htamp", "drone-5", 295.0, 0.3), kept("htamp", "drone-5", 285.0, 0.5, seed=1)]
    records = [_rec("masp", "drone-5", 150.0), _rec("masp", "drone-20", 330.0), *five,
               kept("mage-x", "drone-20", 500.0, 0.1), kept("h-mappo", "drone-20", 320.0, 0.9)]
    rows = {(r[0], r[1]): r for r in rp.build("drone-claims", records).rows}
    only = rows[("Only MAGE-X and (H)MAPPO of the RL baselines reach SR ≥ 0.9", "drone-5")]
    assert only[3:] == ["(H)MAPPO 1.00, MAPPO 0.40, DARL1N 0.60, HTAMP 0.40, MAGE-X 0.95", "yes"]  # htamp: 2 seeds
    assert rows[("MAGE-X drops at N = 20 (SR < 0.5)", "drone-20")][2:] == ["0.14", "0.10", "yes"]
    assert rows[("(H)MAPPO needs more Steps than MASP", "drone-5")][2:] == ["185.34 vs 138.35", "180.00 vs 150.00",
                                                                           "yes"]
    assert rows[("(H)MAPPO needs more Steps than MASP", "drone-20")][3:] == ["320.00 vs 330.00", "no"]
    assert rows[("(H)MAPPO needs more Steps than MASP (velocity)", "drone-5")][3:] == ["—", "—"]
    assert rows[("MASP CR below every RL baseline's", "drone-5")][3:] == ["0.1000 vs (H)MAPPO 0.1000", "no"]  # a tie
    assert rows[("MASP CR below every RL baseline's", "drone-20")][3:] == ["—", "—"]   # three baselines missing
    records[3] = kept("mage-x", "drone-5", 200.0, 0.5)
    rows = {(r[0], r[1]): r for r in rp.build("drone-claims", records).rows}
    assert rows[("Only MAGE-X and (H)MAPPO of the RL baselines reach SR ≥ 0.9", "drone-5")][4] == "no"


def test_reproduce_evaluates_each_distinct_run_once(monkeypatch, capsys):
    """The faithful and MPE tables both read the shipped MASP on mpe-5; the claims read the MPE table's records."""
    import argparse

    import masp_lite.cli.reproduce as cli
    calls = []

    def fake(m, sc, **kw):
        calls.append(json.dumps([m, sc, kw.get("method_options"), kw.get("checkpoint"), kw.get("num_envs")],
                                sort_keys=True))
        options = {**kw.get("method_options", {}), **({"checkpoint": kw["checkpoint"]} if kw.get("checkpoint") else {})}
        extra = {k: v for k, v in (("method_options", options), ("num_envs", kw.get("num_envs"))) if v}
        return _rec(m, sc, **extra)
    monkeypatch.setattr(rp, "evaluate", fake)
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    cli.run(parser.parse_args(["--table", "faithful", "--table", "mpe", "--table", "claims", "--format", "text",
                               "--quick"]))
    assert calls and len(calls) == len(set(calls))
    assert calls.count(json.dumps(["masp", "mpe-5", {}, None, None], sort_keys=True)) == 1
    assert "MPE, N = 5 / 20 / 50" in capsys.readouterr().out


def test_readme_claims_are_the_ones_the_records_give():
    """README.md's claims blocks and the table beyond the paper (``<!-- reproduce NAME -->``) are what
    ``reproduce`` prints now."""
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert {m.group(2) for m in rp.BLOCK.finditer(text)} == {"claims", "drone-claims", "ablation-claims", "beyond"}
    assert rp.fill_blocks(text, rp.load_records()) == text, "README.md: a claims block is stale (rp.fill_blocks)"


def test_the_table_beyond_the_paper_pools_masp_minmaxs_three_training_seeds():
    records = rp.load_records()
    table = rp.build("beyond", records)
    assert "—" not in rp.render(table, "text").split("Legend")[0] and "paper" not in {r[2] for r in table.rows}
    for sc in ("mpe-5", "mpe-20", "mpe-50", "mpe-20to10", "mpe-50to20"):
        mine = rp.pick(records, "masp-minmax", sc, rp.MINMAX)
        assert mine["training_seeds"] == [0, 1, 2], sc
    jobs = rp.evaluation_jobs("beyond")
    assert ("masp-minmax", "mpe-50to20", {"checkpoint": "results/training/masp-minmax/mpe-50-seed2.pt"}) in jobs
    assert not any(m == "masp-minmax" and "mpe-5-seed" in kw["checkpoint"] for m, sc, kw in jobs if sc != "mpe-5")
