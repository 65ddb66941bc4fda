"""``bench busy``: interleaved idle / busy repetitions, a competitor in its own session, the 2-CPU pinning.

No timing is asserted (speed targets live in the benchmark's printed ratios): the ratio arithmetic is
checked on a loop that reports made-up durations, and the command on tiny budgets for its output.
"""
import json
import os

import pytest

from masp_lite.__main__ import main
from masp_lite.bench import busy
from masp_lite.bench.competing import BUSY_CPUS, busy_warning, competing_process, other_cpu_use, pinned


def test_each_round_pairs_an_idle_and_a_busy_repetition_in_alternating_order(monkeypatch):
    state, sides = {"busy": False}, []

    class Competitor:
        def __enter__(self):
            state["busy"] = True

        def __exit__(self, *exc):
            state["busy"] = False

    rate = busy._rate
    monkeypatch.setattr(busy, "_rate", lambda call, s: sides.append("busy" if state["busy"] else "idle") or
                        rate(call, s))

    def call():  # reports 4 ms of work when busy, 2 ms when idle: a busy / idle ratio of exactly 0.5
        return 0.004 if state["busy"] else 0.002

    r = busy.interleaved_ratio(call, seconds=0.001, rounds=4, competitor=Competitor)
    assert r["ratios"] == pytest.approx([0.5] * 4) and r["ratio"] == pytest.approx(0.5)
    assert r["idle_per_s"] == pytest.approx(500) and r["busy_per_s"] == pytest.approx(250)
    assert sides == ["idle", "busy", "busy", "idle", "idle", "busy", "busy", "idle"]


@pytest.mark.skipif(not hasattr(os, "getsid"), reason="sessions are POSIX")
def test_the_competitor_spins_in_a_session_of_its_own_and_ends_with_the_block():
    with competing_process() as proc:
        assert proc.poll() is None and os.getsid(proc.pid) != os.getsid(0)
        if os.path.exists(f"/proc/{proc.pid}/stat"):
            state = open(f"/proc/{proc.pid}/stat").read().rsplit(")", 1)[1].split()[0]
            assert state in "RS"  # running (or just preempted), not stopped
    assert proc.poll() is not None


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs CPU affinity and at least 2 CPUs")
def test_pinning_keeps_every_thread_on_the_cpus_asked_and_restores_them():
    import threading
    before = os.sched_getaffinity(0)
    with pinned(1) as cpus:
        assert cpus == 1 and len(os.sched_getaffinity(0)) == 1
        seen = []
        t = threading.Thread(target=lambda: seen.append(os.sched_getaffinity(0)))  # a thread started inside
        t.start()
        t.join()
        assert len(seen[0]) == 1
    assert os.sched_getaffinity(0) == before
    with pinned(len(before) + 5) as cpus:  # more than the machine has: nothing to pin
        assert cpus == len(before) and os.sched_getaffinity(0) == before


def test_the_busy_warning_says_how_busy_and_only_when_busy():
    assert busy_warning(None) is None and busy_warning(0.0) is None and busy_warning(BUSY_CPUS / 2) is None
    text = busy_warning(1.5)
    assert text.startswith("warning: the machine is busy") and "1.5 of" in text and "idle machine" in text
    use = other_cpu_use(0.05)
    assert use is None or use >= 0


def test_bench_busy_prints_a_ratio_per_loop_at_the_products_thread_counts(tmp_path, capsys):
    out = tmp_path / "busy.json"
    assert main(["bench", "busy", "--rounds", "1", "--seconds", "0.01", "--worlds", "2", "--train-worlds", "1",
                 "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.count("busy/idle") == 3 and "torch threads wait passively" in text
    r = json.loads(out.read_text())
    assert r["passive_wait"] is True and set(r["loops"]) == {"world", "decide", "train"}
    assert [r["loops"][k]["threads"] for k in ("world", "decide", "train")] == [1, 1, 1]
    for row in r["loops"].values():
        assert row["ratio"] == pytest.approx(row["ratios"][0]) and row["ratio"] > 0
        assert f"busy/idle {row['ratio']:.2f}" in text


@pytest.mark.parametrize("argv,words", [(["--rounds", "0"], "--rounds"), (["--threads", "0"], "--threads"),
                                        (["--seconds", "0"], "--seconds"), (["--cpus", "0"], "--cpus")])
def test_bench_busy_bad_options_are_one_clear_error(argv, words, capsys):
    assert main(["bench", "busy", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {words}") and "Traceback" not in err


@pytest.mark.parametrize("argv", [["decide", "--agents", "5"], ["train", "--scenarios", "mpe-5", "--worlds", "2",
                                                                 "--methods", "masp", "--no-reference"],
                                  ["env", "--seconds", "0.05", "--rounds", "1", "--worlds", "2"]])
def test_every_timing_target_warns_when_the_machine_is_busy(argv, monkeypatch, capsys):
    from masp_lite.bench import competing
    monkeypatch.setattr(competing, "other_cpu_use", lambda sample_s=0.3: 1.7)  # as if 1.7 CPUs were taken
    import importlib
    module = importlib.import_module(f"masp_lite.bench.{argv[0]}")
    if hasattr(module, "other_cpu_use"):
        monkeypatch.setattr(module, "other_cpu_use", lambda sample_s=0.3: 1.7)
    assert main(["bench", *argv]) == 0
    assert "warning: the machine is busy: other programs keep 1.7 of" in capsys.readouterr().out
