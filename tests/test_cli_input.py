"""The first hour's rough edges: every bad command-line value is one clear error, and no result is lost."""
import json
from pathlib import Path

import pytest

from masp_lite.__main__ import main
from masp_lite.bench import TARGETS
from masp_lite.cli.evaluate import write_record
from masp_lite.evaluation import evaluate
from masp_lite.evaluation.tables import cell
from masp_lite.policies import method_names

FAST = ["evaluate", "--method", "h-greedy", "--scenario", "mpe-5", "--episodes", "1"]


@pytest.mark.parametrize("argv,message", [
    (["--seeds", "-1"], "seeds: expected ints from 0 to 2**63 - 1, got [-1]"),
    (["--seeds", "0", "0", "0"], "seeds: expected distinct seeds"),
    (["--seeds", "99999999999999999999"], "seeds: expected ints from 0 to 2**63 - 1"),
    (["--json", ""], "--json: expected a file path such as 'out.json', got an empty string"),
    (["--num-envs", "0"], "num_envs: expected a positive int"),
    (["--json", "/proc/out.json"], "is not writable"),
    (["--json", "/dev/full"], "is not a regular file"),
])
def test_bad_values_are_one_clear_error_before_the_run(argv, message, capsys):
    assert main(FAST + argv) == 2
    out = capsys.readouterr()
    assert message in out.err and "Traceback" not in out.err
    assert "h-greedy" not in out.out  # refused before the run: no table printed


def test_a_record_that_cannot_be_written_after_the_run_goes_beside_the_working_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    record = {"method": "h-greedy", "scenario": "mpe-5", "sr": {"mean": 1.0, "std": 0.0}}
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match=r"could not write the record .*written to 'evaluate-h-greedy-mpe-5.json'"):
        write_record(record, tmp_path / "file" / "out.json")
    assert json.loads((tmp_path / "evaluate-h-greedy-mpe-5.json").read_text()) == record
    with pytest.raises(ValueError, match="evaluate-h-greedy-mpe-5-1.json"):  # never over an earlier one
        write_record(record, tmp_path / "file" / "out.json")
    assert write_record(record, tmp_path / "ok" / "out.json") == tmp_path / "ok" / "out.json"


def test_evaluate_help_lists_every_method_and_the_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert all(m in text for m in method_names()) and len(method_names()) == 18
    assert "(default 0 1 2" in text and "(default markdown)" in text and "mpe-50to20" in text


def test_a_team_that_cannot_fit_in_memory_is_refused_with_the_estimate():
    with pytest.raises(ValueError, match=r"5000 agents in 100 worlds side by side need about .* GiB .*N\^2"):
        evaluate("h-greedy", "mpe-50", episodes=100, seeds=[0], overrides={"num_agents": 5000, "world_size": 200.0})


def test_sr_below_one_never_reads_one():
    assert cell((0.999, 0.03)) == "0.999 (0.03)" and cell((0.99996, 0.0)) == "0.99996 (0.00)"
    assert cell((1.0, 0.0)) == "1.00 (0.00)" and cell((0.994, 0.1)) == "0.99 (0.10)"


def test_play_prints_the_episode_and_ends_the_animation_when_solved(tmp_path, capsys):
    from PIL import Image
    out = tmp_path / "ep.gif"
    assert main(["play", "--method", "h-greedy", "--scenario", "mpe-5", "--out", str(out), "--seed", "3"]) == 0
    text = capsys.readouterr().out
    rec = evaluate("h-greedy", "mpe-5", episodes=1, seeds=[3], num_envs=1)  # the same episode, as evaluate sees it
    assert rec["sr"]["mean"] == 1.0 and rec["steps"]["mean"] < 25       # solved before mpe-5's horizon
    assert f"SR 1.00  Steps {rec['steps']['mean']:.0f}  CR {rec['cr']['mean']:.2f}" in text
    assert Image.open(out).n_frames == rec["steps"]["mean"] + 1        # the reset frame, then one per step


def test_the_readme_lists_every_method():
    from pathlib import Path
    row = next(line for line in (Path(__file__).parents[1] / "README.md").read_text().splitlines()
               if line.startswith("| `masp_lite.policies`"))
    assert all(f"`{m}`" in row for m in method_names()) and f"({len(method_names())})" in row


@pytest.mark.parametrize("argv", [["bench", "--help"], *(["bench", t, "--help"] for t in
                                                        ("env", "decide", "planners", "drones", "train", "busy"))])
def test_every_bench_help_ends_with_examples(argv, capsys):
    with pytest.raises(SystemExit):
        main(argv)
    text = capsys.readouterr().out
    assert "examples:" in text and f"-m masp_lite {' '.join(argv[:-1])}" in text


def test_bench_env_ratios_follow_from_the_printed_rates(tmp_path, capsys):
    import re
    out = tmp_path / "env.json"
    assert main(["bench", "env", "--seconds", "0.2", "--rounds", "2", "--threads", "1", "--worlds", "4",
                 "--json", str(out)]) == 0
    text, r = capsys.readouterr().out, json.loads(out.read_text())
    rates = {k: float(v.replace(",", "")) for k, v in re.findall(r"(masp-lite|TorchRL face|beside it|mpe2 simple_spread"
                                                               r"_v3 \(1 episode\))\s+.*?([\d,]+) agent-steps/s", text)}
    if r["mpe2_agent_steps_per_s"] is not None:
        assert r["ratio"]["value"] == r["masp_agent_steps_per_s"]["4"] / r["mpe2_agent_steps_per_s"]
        shown = float(re.search(r"ratio masp-lite / mpe2 at 4 worlds: ([\d,]+)x", text)[1].replace(",", ""))
        assert abs(shown - rates["masp-lite"] / rates["mpe2 simple_spread_v3 (1 episode)"]) <= 1
    if r["torchrl_agent_steps_per_s"] is not None:
        shown = float(re.search(r"overhead of the TorchRL face at 4 worlds: ([\d.]+)x", text)[1])
        assert abs(shown - rates["beside it"] / rates["TorchRL face"]) < 0.01


@pytest.mark.parametrize("where,words", [("/proc/x.gif", "is not writable"), ("FILE/x.gif", "is a file, not a folder")])
def test_play_out_that_cannot_be_written_is_one_clear_error_before_the_episode(tmp_path, capsys, where, words):
    (tmp_path / "FILE").write_text("x")
    out = where.replace("FILE", str(tmp_path / "FILE"))
    assert main(["play", "--method", "h-greedy", "--scenario", "mpe-5", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out") and words in err and "Traceback" not in err


def test_a_3d_episodes_numbers_are_the_evaluations_of_the_same_episode(tmp_path):
    from masp_lite.viz.play import play
    path, got = play("h-greedy", "drone-5", tmp_path / "ep.html", seed=1, overrides={"horizon": 60})
    rec = evaluate("h-greedy", "drone-5", episodes=1, seeds=[1], overrides={"horizon": 60}, num_envs=1)
    assert path.read_text().startswith("<") and got == {k: rec[k]["mean"] for k in ("sr", "steps", "cr")}


# ------------------------------------------------------------------ a newcomer's machine (issue 56)
ROOTLESS = "/masp-lite-no-such-folder"  # a folder that would be made at the file system's root
#: Every option that names one file to write, as the argv before its path: evaluate's --json, play's --out and each
#: bench target's --json. (train --out names a folder, which train makes.)
FILE_OPTIONS = {"evaluate": FAST + ["--json"], "play": ["play", "--method", "h-greedy", "--scenario", "mpe-5", "--out"],
                **{f"bench-{t}": ["bench", t, "--json"] for t in TARGETS}}


@pytest.mark.parametrize("folder", [ROOTLESS, f"{ROOTLESS}/deeper", "new", "new/deeper"])
@pytest.mark.parametrize("command", list(FILE_OPTIONS))
def test_a_file_in_a_folder_that_does_not_exist_is_one_clear_error(command, folder, tmp_path, monkeypatch, capsys):
    """``--json /nonexistent/x.json`` made the folder at the file system's root without a word; a file option
    now refuses any folder that does not exist, names it and makes nothing (as a shell's ``>`` does)."""
    if Path(ROOTLESS).exists():
        pytest.skip(f"{ROOTLESS} exists on this machine")
    monkeypatch.chdir(tmp_path)
    argv = FILE_OPTIONS[command]
    name = "x.gif" if command == "play" else "x.json"
    assert main([*argv, f"{folder}/{name}"]) == 2
    out = capsys.readouterr()
    assert out.err == (f"error: {argv[-1]} '{folder}/{name}': the folder '{folder}' does not exist; expected a file "
                       f"in an existing folder (create the folder first, or write '{name}' elsewhere)\n")
    assert out.out == ""  # refused before anything ran
    assert not Path(ROOTLESS).exists() and list(tmp_path.iterdir()) == []  # and nothing made


def test_evaluate_threads_default_to_one_as_the_records_and_are_checked(tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(FAST + ["--seeds", "0", "--set", "horizon=4", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["threads"] == 1
    assert main(FAST + ["--seeds", "0", "--set", "horizon=4", "--threads", "2", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["threads"] == 2
    assert main(FAST + ["--threads", "0"]) == 2
    assert "--threads: expected a positive int, got 0" in capsys.readouterr().err


def test_the_progress_bars_last_frame_shows_the_total(capsys):
    """``evaluate --episodes 1`` on three seeds: tqdm draws at most every 0.1 s, so without a last refresh
    the final frame stopped short (536/900)."""
    import re
    evaluate("h-greedy", "mpe-5", episodes=1, seeds=[0, 1, 2], progress=True)
    frames = re.findall(r"(\d+)/(\d+) \[", capsys.readouterr().err)
    assert frames and frames[-1] == ("54", "54")  # 3 seeds x 1 batch x 18 steps


def test_evaluate_never_writes_its_record_over_its_checkpoint_or_another_file(tmp_path, capsys):
    from masp_lite.weights import default_checkpoint
    weights = tmp_path / "w.pt"
    weights.write_bytes(default_checkpoint("mpe-5").read_bytes())
    before = weights.read_bytes()
    run = ["evaluate", "--method", "masp", "--scenario", "mpe-5", "--episodes", "1", "--seeds", "0",
           "--checkpoint", str(weights), "--json"]
    assert main(run + [str(weights)]) == 2
    assert "is the --checkpoint file; expected another path" in capsys.readouterr().err
    assert weights.read_bytes() == before
    (tmp_path / "notes.txt").write_text("my notes\n")
    assert main(run + [str(tmp_path / "notes.txt")]) == 2
    assert "holds something other than a JSON record" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "my notes\n"
    (tmp_path / "old.json").write_text('{"method": "masp"}\n')  # an earlier record is replaced
    assert main(run + [str(tmp_path / "old.json")]) == 0
    assert json.loads((tmp_path / "old.json").read_text())["episodes_per_seed"] == 1


def test_a_record_that_does_not_fit_on_the_disk_leaves_the_earlier_one_whole(tmp_path):
    """A file-size limit stands for a full disk: the new record cannot be written past 16 bytes."""
    import os
    import subprocess
    import sys
    from pathlib import Path
    earlier = tmp_path / "out.json"
    earlier.write_text('{"a": 1}\n')
    script = (
        "import json, resource, signal, sys\n"
        "from pathlib import Path\n"
        "from masp_lite.cli.evaluate import write_record\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (16, 16))\n"
        "try:\n"
        "    write_record({'method': 'h-greedy', 'scenario': 'mpe-5', 'pad': 'x' * 500}, Path(sys.argv[1]))\n"
        "except ValueError as e:\n"
        "    print('refused:', e)\n")
    done = subprocess.run([sys.executable, "-c", script, str(earlier)], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert "refused: --json" in done.stdout, done.stderr
    assert json.loads(earlier.read_text()) == {"a": 1}  # the earlier record as it was, not truncated
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]  # no temporary file left behind


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-1"], "--seed: expected an int from 0 to 2**63 - 1"),
    (["--threads", "10000"], "--threads: expected an int from 1 to"),
    (["--threads", "0"], "--threads: expected an int from 1 to"),
])
def test_train_refuses_what_evaluate_refuses_before_anything_runs(argv, message, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--scenario", "mpe-5", "--out", str(out), "--quiet", "--set", "updates=1", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and not out.exists()


def test_a_large_int_setting_is_read_exactly_not_through_a_float():
    from masp_lite.training import parse_config
    cfg, _ = parse_config(["updates=9007199254740993"])
    assert cfg.run.updates == 9007199254740993 and isinstance(cfg.run.updates, int)
    assert parse_config(["updates=1e3"])[0].run.updates == 1000
