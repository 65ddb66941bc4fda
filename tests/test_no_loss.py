"""Nothing lost, nothing silently wrong: training that cannot go on stops before it writes anything."""
import pytest
import torch

from masp_lite.__main__ import main
from masp_lite.config import TrainConfig
from masp_lite.training import train

TINY = dict(num_envs=3, updates=2, checkpoint_every=1, eval_every=0, eval_episodes=2, ppo_epochs=1,
            num_minibatches=2, width=8)


def _cfg(**flat) -> TrainConfig:
    return TrainConfig.from_flat({**TINY, **flat})


@pytest.mark.parametrize("setting", ["lr=inf", "lr=nan", "lr=5", "clip=inf", "clip=3", "gamma=nan",
                                     "max_grad_norm=inf", "huber_delta=nan", "entropy_coef=inf"])
def test_settings_that_cannot_train_are_refused_up_front(tmp_path, capsys, setting):
    out = tmp_path / "run"
    assert main(["train", "--scenario", "mpe-5", "--out", str(out), "--quiet", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert f"{setting.split('=')[0]}: expected a finite number" in err and "Traceback" not in err
    assert not out.exists()


def _state(out):
    return torch.load(out / "state.pt", weights_only=True)


def test_a_non_finite_update_stops_the_run_before_anything_is_written(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    state = _state(out)
    # one corrupted optimizer value: finite, but Adam's square root of it is not
    first = next(iter(state["cae_opt"]["state"].values()))
    first["exp_avg_sq"].view(-1)[0] = -1.0
    torch.save(state, out / "state.pt")
    before = {f: (out / f).read_bytes() for f in ("state.pt", "weights.pt", "progress.csv", "manifest.json")}
    stopped = r"training stopped at iteration 2: the .* is nan; nothing was written, .*iteration 1\) is intact"
    with pytest.raises(ValueError, match=stopped):
        train("mpe-5", _cfg(), out, progress=False, resume=True)
    assert {f: (out / f).read_bytes() for f in before} == before


def test_a_state_with_non_finite_values_is_refused_naming_file_and_value(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    state = _state(out)
    name = next(iter(state["nets"]))
    state["nets"][name].view(-1)[0] = float("nan")
    torch.save(state, out / "state.pt")
    with pytest.raises(ValueError, match=rf"state.pt: expected a training state with finite values; value nets.{name}"):
        train("mpe-5", _cfg(), out, progress=False, resume=True)


def test_a_second_run_into_the_same_folder_is_refused_and_a_stale_lock_taken_over(tmp_path):
    import subprocess
    import sys
    out = tmp_path / "run"
    out.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / ".lock").write_text(f"{holder.pid}\n")
        with pytest.raises(ValueError, match=rf"being trained by process {holder.pid}"):
            train("mpe-5", _cfg(updates=1), out, progress=False)
        assert not (out / "state.pt").exists()
    finally:
        holder.kill()
        holder.wait()
    train("mpe-5", _cfg(updates=1), out, progress=False)  # its holder is gone: a stale lock, taken over
    assert (out / "manifest.json").exists() and not (out / ".lock").exists()  # released at the end
    with pytest.raises(ValueError, match="stopped"):  # released on an error too
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True,
              on_iteration=lambda t: (_ for _ in ()).throw(ValueError("stopped")))
    assert not (out / ".lock").exists()


def test_an_out_folder_that_cannot_be_written_is_one_clear_error(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["train", "--scenario", "mpe-5", "--out", str(tmp_path / "file" / "run"), "--quiet",
                 "--set", "updates=1"]) == 2
    err = capsys.readouterr().err
    assert "expected a folder that can be written" in err and "Traceback" not in err


def test_resume_keeps_the_history_honest(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=2), out, progress=False)
    with pytest.raises(ValueError, match=r"updates=1: expected at least the 2 iterations"):
        train("mpe-5", _cfg(updates=1), out, progress=False, resume=True)
    m = train("mpe-5", _cfg(updates=2), out, progress=False, resume=True)  # ends the run where it is
    assert m["iterations"] == m["config"]["updates"] == 2
    csv = (out / "progress.csv").read_bytes()
    (out / "progress.csv").write_bytes(b"\x00\xff garbage")
    with pytest.raises(ValueError, match="progress.csv: expected the history of the 2 iterations"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    (out / "progress.csv").unlink()
    with pytest.raises(ValueError, match="the file is missing"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    (out / "progress.csv").write_bytes(csv)
    assert train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)["iterations"] == 3


def test_a_run_folders_weights_are_checked_against_the_hash_its_manifest_recorded(tmp_path):
    from masp_lite.weights import load_weights
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    nets, _ = load_weights(out / "weights.pt", any_scenario=True)     # whole: loads
    raw = torch.load(out / "weights.pt", weights_only=True)
    name = next(iter(raw["state_dict"]))
    raw["state_dict"][name].zero_()                                       # a zeroed tensor
    torch.save(raw, out / "weights.pt")
    with pytest.raises(ValueError, match="differ from the SHA-256 its run recorded"):
        load_weights(out / "weights.pt", any_scenario=True)
    raw["state_dict"][name].fill_(float("nan"))
    torch.save(raw, tmp_path / "loose.pt")                                # not in a run folder: no hash to check
    with pytest.raises(ValueError, match=rf"parameter '{name}' holds NaN or inf"):
        load_weights(tmp_path / "loose.pt", any_scenario=True)


def test_resuming_a_finished_run_drops_its_stale_manifest_until_it_finishes_again(tmp_path):
    from masp_lite.weights import load_weights
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    with pytest.raises(ValueError, match="stopped"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True,
              on_iteration=lambda t: (_ for _ in ()).throw(ValueError("stopped")))
    assert not (out / "manifest.json").exists()
    load_weights(out / "weights.pt", any_scenario=True)                   # the newer weights load
    train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    load_weights(out / "weights.pt", any_scenario=True)


def test_init_and_resume_mismatches_name_both_sides(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    with pytest.raises(ValueError, match=r"differs in \['lr'\] \(lr: run 0.0007, now 0.001\)"):
        train("mpe-5", _cfg(updates=2, lr=1e-3), out, progress=False, resume=True)
    with pytest.raises(ValueError, match=r"width: --init 8, configured 16"):
        train("mpe-5", _cfg(updates=1, width=16), tmp_path / "wide", progress=False, init=out / "weights.pt")
    mlp = tmp_path / "mlp"
    train("mpe-5", _cfg(updates=1, goal_matcher="mlp", executor="mlp"), mlp, progress=False)
    with pytest.raises(ValueError, match=r"team_size: --init 5, configured 20.*one team size"):
        train("mpe-20", _cfg(updates=1, goal_matcher="mlp", executor="mlp"), tmp_path / "mlp20", progress=False,
              init=mlp / "weights.pt")
    # weights of another world: refused unless this run names its world (a deliberate move, as the shipped
    # mpe-20 chain's last stage made from mpe2's world into the paper's)
    mpe2 = tmp_path / "mpe2"
    train("mpe-5", _cfg(updates=1), mpe2, progress=False, overrides={"integration": "mpe2", "landmark_spawn": "whole"})
    with pytest.raises(ValueError, match=r"trained in the world integration=mpe2, landmark_spawn=whole, this run's "
                                         r"is integration=velocity_first.*--set integration=velocity_first"):
        train("mpe-20", _cfg(updates=1), tmp_path / "moved", progress=False, init=mpe2 / "weights.pt")
    train("mpe-20", _cfg(updates=1), tmp_path / "moved", progress=False, init=mpe2 / "weights.pt",
          overrides={"integration": "velocity_first", "landmark_spawn": "central"})


# ------------------------------------------------------------------ nothing the user did not name is replaced
def test_a_fresh_run_never_replaces_other_files_in_an_existing_folder(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    mine = {"manifest.json": b'{"mine": 1}\n', "progress.csv": b"a,b\n1,2\n", "weights.pt": b"PK my weights"}
    for name, data in mine.items():
        (out / name).write_bytes(data)
    assert main(["train", "--scenario", "mpe-5", "--out", str(out), "--quiet", "--set", "updates=1",
                 "--set", "num_envs=2", "--set", "width=8", "--set", "eval_every=0"]) == 2
    err = capsys.readouterr().err
    assert "holds other files (manifest.json, progress.csv, weights.pt)" in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == mine  # nothing written, nothing replaced
    empty = tmp_path / "empty"
    empty.mkdir()
    train("mpe-5", _cfg(updates=1), empty, progress=False)  # an empty folder is a new run's
    # a run stopped before its first whole checkpoint (its history written, no state yet) starts again there
    (empty / "state.pt").unlink()
    train("mpe-5", _cfg(updates=1), empty, progress=False)
    assert int(_state(empty)["iterations"]) == 1


def test_an_empty_out_is_refused_not_read_as_the_default_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--scenario", "mpe-5", "--out", "", "--quiet", "--set", "updates=1"]) == 2
    assert "--out: expected a folder path" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("change, words", [
    (lambda s: s.update(iterations=-3), "field 'iterations' is -3; expected a count >= 0"),
    (lambda s: s.update(iterations=True), "field 'iterations' is a bool"),
    (lambda s: s.pop("nets"), "field 'nets' is missing"),
    (lambda s: s.update(config=[1, 2]), "field 'config' is a list"),
    (lambda s: s.update(overrides=[1]), "field 'overrides' is a list; expected a dict"),
    (lambda s: s.update(generator=torch.zeros(3, dtype=torch.uint8)), "could not load it (RuntimeError"),
    (lambda s: s["gm_opt"]["param_groups"][0].update(lr=10.0),
     "its optimizer setting gm_opt.0.lr is 10.0, the configuration's is 0.0007"),
])
def test_a_damaged_state_is_refused_naming_its_field_and_the_history_is_kept(tmp_path, change, words):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    state = _state(out)
    change(state)
    torch.save(state, out / "state.pt")
    history = (out / "progress.csv").read_bytes()
    with pytest.raises(ValueError, match="state.pt") as e:
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    assert words in str(e.value)
    assert (out / "progress.csv").read_bytes() == history


def test_a_state_that_is_not_a_dict_or_a_folder_in_its_place_is_one_clear_error(tmp_path):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    torch.save([1, 2], out / "state.pt")
    with pytest.raises(ValueError, match="expected a training state .*got a list"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    (out / "state.pt").unlink()
    (out / "state.pt").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)


@pytest.mark.parametrize("name", ["progress.csv", "manifest.json", "weights.pt"])
def test_a_folder_where_a_run_file_belongs_is_refused_before_training(tmp_path, name):
    out = tmp_path / "run"
    train("mpe-5", _cfg(updates=1), out, progress=False)
    (out / name).unlink()
    (out / name).mkdir()
    state = (out / "state.pt").read_bytes()
    with pytest.raises(ValueError, match=rf"{name} is a folder or another non-file; expected the run's {name}"):
        train("mpe-5", _cfg(updates=3), out, progress=False, resume=True)
    assert (out / "state.pt").read_bytes() == state  # nothing trained, nothing written


def test_resume_with_other_torch_threads_is_refused(tmp_path):
    out = tmp_path / "run"
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        train("mpe-5", _cfg(updates=1), out, progress=False)
        torch.set_num_threads(2)
        with pytest.raises(ValueError, match=r"trained with 1 torch thread\(s\), now 2; resume with --threads 1"):
            train("mpe-5", _cfg(updates=2), out, progress=False, resume=True)
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize("errno_name", ["ENOSPC", "EROFS"])
def test_a_full_or_read_only_disk_stops_training_with_one_line_and_the_resume_command(
        tmp_path, capsys, monkeypatch, errno_name):
    import errno
    import os
    import shlex

    import masp_lite.files as files
    out = tmp_path / "run"
    real = os.replace

    def failing(src, dst):  # the disk fills up (or turns read-only) once the first checkpoint is written
        if (out / "state.pt").exists():
            raise OSError(getattr(errno, errno_name), os.strerror(getattr(errno, errno_name)))
        return real(src, dst)
    monkeypatch.setattr(files.os, "replace", failing)
    argv = ["train", "--scenario", "mpe-5", "--out", str(out), "--quiet", "--threads", "1"] + \
        [x for k, v in {**TINY, "updates": 3}.items() for x in ("--set", f"{k}={v}")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert f"could not write the run folder {out} ({os.strerror(getattr(errno, errno_name))})" in err
    assert f"the last checkpoint ({out / 'state.pt'}, iteration 1) is intact" in err
    assert int(_state(out)["iterations"]) == 1
    assert not [p for p in out.iterdir() if p.name.startswith(files.TMP_PREFIX)]  # no half-written file left
    monkeypatch.setattr(files.os, "replace", real)  # space again: the printed command finishes the run
    command = shlex.split(err.split("resume with: ", 1)[1])
    assert command[command.index("masp_lite") + 1] == "train" and command[-1] == "--resume"
    assert main(command[command.index("masp_lite") + 1:]) == 0
    assert int(_state(out)["iterations"]) == 3


# ------------------------------------------------------------------ one atomic write, one bounded reader
def test_an_orphaned_temporary_file_is_removed_by_the_next_write_and_a_live_one_kept(tmp_path):
    import subprocess
    import sys

    from masp_lite.files import TMP_PREFIX, atomic_write
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    try:
        orphan = tmp_path / f"{TMP_PREFIX}{dead.pid}.0000.out.json"
        live = tmp_path / f"{TMP_PREFIX}{holder.pid}.0000.out.json"
        orphan.write_text("{half")
        live.write_text("{half")
        atomic_write(tmp_path / "out.json", "{}\n")
        assert not orphan.exists() and live.exists() and (tmp_path / "out.json").read_text() == "{}\n"
    finally:
        holder.kill()
        holder.wait()


def test_concurrent_writers_leave_one_whole_file(tmp_path):
    import json
    import threading

    from masp_lite.files import atomic_write
    path = tmp_path / "record.json"

    def writer(k):
        for i in range(40):
            atomic_write(path, json.dumps({"writer": k, "i": i, "pad": "x" * (1000 * k)}))
    threads = [threading.Thread(target=writer, args=(k,)) for k in range(3)]
    for t in threads:
        t.start()
    seen = 0
    while any(t.is_alive() for t in threads):
        if path.exists():
            json.loads(path.read_text())  # never a mix or a truncation
            seen += 1
    for t in threads:
        t.join()
    assert json.loads(path.read_text())["i"] == 39 and seen > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["record.json"]


def test_an_atomic_write_keeps_a_replaced_files_permissions(tmp_path):
    import stat

    from masp_lite.files import atomic_write
    private = tmp_path / "private.json"
    private.write_text("{}")
    private.chmod(0o600)
    atomic_write(private, "{\"a\": 1}")
    assert stat.S_IMODE(private.stat().st_mode) == 0o600 and private.read_text() == '{"a": 1}'
    assert stat.S_IMODE(atomic_write(tmp_path / "new.json", "{}").stat().st_mode) == 0o644


def test_the_bounded_reader_refuses_pipes_devices_folders_and_large_files(tmp_path):
    import os

    from masp_lite.files import read_bounded
    os.mkfifo(tmp_path / "x.json")
    with pytest.raises(ValueError, match="not a regular file"):
        read_bounded(tmp_path / "x.json")  # at once: no writer is waited for
    with pytest.raises(ValueError, match="not a regular file"):
        read_bounded("/dev/zero")
    with pytest.raises(ValueError, match="is a folder"):
        read_bounded(tmp_path)
    (tmp_path / "big").write_bytes(b"x" * 101)
    with pytest.raises(ValueError, match="101 bytes, more than the 100"):
        read_bounded(tmp_path / "big", limit=100)
    assert read_bounded(tmp_path / "big", limit=101) == b"x" * 101


#: Writes that do not go through :func:`masp_lite.files.atomic_write`, each with why it may not.
_OWN_WRITES = {
    ("training.py", "fdopen"): "the run lock: created with O_EXCL, its creation is the lock",
    ("cli/evaluate.py", "write_bytes"): "an empty probe file that tells whether a folder can be written",
}


def _tmp(call) -> bool:
    """Whether a call writes to ``tmp`` or ``str(tmp)``, the path :func:`masp_lite.files.atomic_target` gives."""
    import ast
    target = call.args[0] if call.args else None
    if isinstance(target, ast.Call) and isinstance(target.func, ast.Name) and target.func.id == "str" and target.args:
        target = target.args[0]
    return isinstance(target, ast.Name) and target.id == "tmp"


def _calls(path):
    """(call node, name, owner, open modes) of every call in the module at ``path``: ``name`` the called
    function or method, ``owner`` the name it is called on (``json`` in ``json.load``), ``modes`` the constant
    mode strings it is given (``Path.open("w")`` takes its mode first, ``open(p, "w")`` second)."""
    import ast
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        owner = f.value.id if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) else ""
        mode_at = 0 if isinstance(f, ast.Attribute) and name == "open" and owner != "os" else 1
        modes = [a.value for a in node.args[mode_at:mode_at + 1] + [k.value for k in node.keywords if k.arg == "mode"]
                 if isinstance(a, ast.Constant) and isinstance(a.value, str)]
        yield node, name, owner, modes


def _writes(path):
    """(name, line) of every call in ``path`` that writes a file: ``open``/``fdopen`` in a writing mode,
    ``write_text``, ``write_bytes``, ``torch.save`` to anything but an in-memory buffer, ``json.dump``,
    ``nbformat.write``, and a movie's ``save`` (unless to an :func:`~masp_lite.files.atomic_target` path)."""
    import ast
    found = []
    for node, name, owner, modes in _calls(path):
        writing = any(set(m) & set("wax+") for m in modes)
        first = node.args[1] if len(node.args) > 1 else None
        to_memory = isinstance(first, ast.Name) and first.id in ("buf", "buffer")
        if (name in ("open", "fdopen") and writing) or name in ("write_text", "write_bytes") or \
                (name == "save" and owner == "torch" and not to_memory) or (name == "dump" and owner == "json") or \
                (name == "write" and owner == "nbformat") or (name == "save" and owner == "anim" and not _tmp(node)):
            found.append((name, node.lineno))
    return found


def test_every_file_the_product_writes_goes_through_the_one_atomic_write():
    from pathlib import Path

    package = Path(__file__).resolve().parents[1] / "masp_lite"
    stray = [f"{p.relative_to(package)}:{line} {name}" for p in sorted(package.rglob("*.py")) if p.name != "files.py"
             for name, line in _writes(p) if (str(p.relative_to(package)), name) not in _OWN_WRITES]
    assert stray == [], "write these through masp_lite.files.atomic_write (or atomic_target)"


#: Reads that do not go through :func:`masp_lite.files.read_bounded`, each with why it may not.
_OWN_READS = {
    ("envs/checks.py", "open"): "/proc/meminfo, the machine's memory",
    ("bench/competing.py", "open"): "/proc/stat, how busy the machine's CPUs are",
    ("evaluation/evaluate.py", "open"): "/proc/meminfo, the machine's memory",
    ("weights/__init__.py", "read_text"): "the package's own weights manifests",
    ("cli/evaluate.py", "open"): "the first 64 bytes of an existing --json regular file (is it a record?)",
    ("viz/meshcat3d.py", "open"): "meshcat's own viewer script, from its installed package",
    ("course/generate.py", "read_text"): "the package's shipped learner notebooks, compared with fresh ones",
}


def _reads(path):
    """(name, line) of every call in ``path`` that reads a file: ``open`` in a reading mode, ``read_text``,
    ``read_bytes``, ``json.load``, ``nbformat.read`` and ``torch.load`` of anything but an in-memory buffer."""
    import ast
    found = []
    for node, name, owner, modes in _calls(path):
        first = node.args[0] if node.args else None
        in_memory = isinstance(first, ast.Call) and getattr(first.func, "attr", "") == "BytesIO"
        if (name == "open" and owner != "os" and not any(set(m) & set("wax") for m in modes)) or \
                name in ("read_text", "read_bytes") or (name == "load" and owner == "json") or \
                (name == "read" and owner == "nbformat") or (name == "load" and owner == "torch" and not in_memory):
            found.append((name, node.lineno))
    return found


def test_every_file_the_product_reads_goes_through_the_one_bounded_reader():
    from pathlib import Path
    package = Path(__file__).resolve().parents[1] / "masp_lite"
    stray = [f"{p.relative_to(package)}:{line} {name}" for p in sorted(package.rglob("*.py")) if p.name != "files.py"
             for name, line in _reads(p) if (str(p.relative_to(package)), name) not in _OWN_READS]
    assert stray == [], "read these through masp_lite.files.read_bounded"


def test_a_training_run_that_cannot_fit_in_memory_is_refused_with_the_estimate(tmp_path, monkeypatch):
    import importlib
    evaluation = importlib.import_module("masp_lite.evaluation.evaluate")  # the module, not the function
    monkeypatch.setattr(evaluation, "_available_bytes", lambda: 2 * 2**30)  # a machine with 2 GiB free
    out = tmp_path / "run"
    with pytest.raises(ValueError, match=r"20 agents in 50000 worlds side by side need about 3.0 GiB .* more than "
                                         r"the 2.0 GiB available; pass num_envs=\d+ \(--set num_envs=\d+\)"):
        train("mpe-20", _cfg(num_envs=50_000), out, progress=False)
    assert not out.exists()
