"""reproduce trusts no record: each is validated on load; its text output fits a terminal."""
import json
import shutil
from pathlib import Path

import pytest

from masp_lite.__main__ import main
from masp_lite.reproduction.reproduce import _fewer_text, load_records, validate_record

ROOT = Path(__file__).resolve().parents[1]
GOOD = json.loads((ROOT / "results" / "mpe" / "masp_mpe-5.json").read_text())


def _folder(tmp_path, rec=None, raw=None):
    folder = tmp_path / "records"
    folder.mkdir(exist_ok=True)
    path = folder / "r.json"
    path.write_bytes(raw if raw is not None else json.dumps(rec).encode())
    return folder, path


@pytest.mark.parametrize("change,field", [
    (lambda r: r["steps"].update(mean=-5.0), "steps.mean"),
    (lambda r: r["steps"].update(mean=float("nan")), "steps.mean"),
    (lambda r: r["sr"].update(mean=7.5), "sr.mean"),
    (lambda r: r["sr"].update(mean="0.99"), "sr.mean"),
    (lambda r: r["cr"].update(std=-1.0), "cr.std"),
    (lambda r: r.pop("sr"), "sr"),
    (lambda r: r.update(scenario="mpe-7"), "scenario"),
    (lambda r: r.update(method="nope"), "method"),
    (lambda r: r.update(seeds=[0, 0]), "seeds"),
    (lambda r: r.update(world={"integration": "other"}), "world"),
])
def test_a_bad_record_is_one_error_naming_the_file_and_the_field(tmp_path, change, field):
    rec = json.loads(json.dumps(GOOD))
    change(rec)
    folder, path = _folder(tmp_path, rec)
    with pytest.raises(ValueError, match=rf"{path}: field '{field}': expected"):
        load_records(folder)


@pytest.mark.parametrize("raw", [b"", json.dumps(GOOD).encode()[:40], b"\x89PNG\x00\xff", b"[1, 2]"])
def test_an_unreadable_or_non_object_file_is_one_error_naming_it(tmp_path, raw):
    folder, path = _folder(tmp_path, raw=raw)
    with pytest.raises(ValueError, match=rf"{path}: expected a JSON"):
        load_records(folder)


def test_the_shipped_records_are_valid_and_a_bad_one_stops_reproduce(tmp_path, capsys):
    assert len(load_records(ROOT / "results")) >= 200
    assert validate_record(GOOD, "x") is GOOD
    folder = tmp_path / "results"
    shutil.copytree(ROOT / "results" / "mpe", folder / "mpe")
    bad = json.loads(json.dumps(GOOD))
    bad["steps"]["mean"] = -5.0
    (folder / "mpe" / "masp_mpe-5.json").write_text(json.dumps(bad))
    assert main(["reproduce", "--table", "claims", "--records", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "masp_mpe-5.json: field 'steps.mean'" in err and "Traceback" not in err


def test_text_output_fits_100_columns_with_one_legend_and_each_note_once(capsys):
    assert main(["reproduce", "--format", "text"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert max(map(len, lines)) <= 100
    assert out.count("Legend:") == 1 and "\\ no episode reached SR 1" in " ".join(out.split())
    notes = [line for line in lines if line.startswith("mean over training seeds")]
    # one line per table and set of seeds (a table whose columns pool different seeds has two), not per column
    assert len(notes) == len(set(notes)) and len(notes) <= 10


def test_a_negative_cut_reads_as_more():
    assert _fewer_text(12.34) == "12.3 % fewer" and _fewer_text(-1.4) == "1.4 % more"


def test_a_pipe_a_dangling_link_or_a_deep_record_is_one_error_naming_it(tmp_path):
    import os
    folder, path = _folder(tmp_path, GOOD)
    os.mkfifo(folder / "x.json")
    with pytest.raises(ValueError, match=r"x.json' is not a regular file"):
        load_records(folder)  # at once: a pipe is not waited on
    (folder / "x.json").unlink()
    (folder / "gone.json").symlink_to(tmp_path / "nowhere.json")
    with pytest.raises(ValueError, match=r"gone.json'.*a link to a missing file"):
        load_records(folder)
    (folder / "gone.json").unlink()
    (folder / "deep.json").write_text('{"method": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(ValueError, match=r"deep.json: expected a JSON evaluation record, could not parse it"):
        load_records(folder)
    (folder / "deep.json").unlink()
    for value in ([1], {"a": 1}):  # unhashable where a name belongs
        path.write_text(json.dumps({**GOOD, "method": value}))
        with pytest.raises(ValueError, match=r"field 'method': expected a name"):
            load_records(folder)


def test_a_folder_named_like_a_record_is_walked_and_a_linked_folder_followed(tmp_path):
    folder, path = _folder(tmp_path, GOOD)
    (folder / "sub.json").mkdir()  # a folder, not a record
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "r2.json").write_text(json.dumps(GOOD))
    (folder / "linked").symlink_to(elsewhere, target_is_directory=True)
    (elsewhere / "back").symlink_to(folder, target_is_directory=True)  # a loop is walked once
    assert sorted(Path(r["path"]).name for r in load_records(folder)) == ["r.json", "r2.json"]


def test_an_empty_records_folder_is_an_error_not_empty_tables(tmp_path, capsys):
    (tmp_path / "records").mkdir()
    assert main(["reproduce", "--table", "claims", "--records", str(tmp_path / "records")]) == 2
    err = capsys.readouterr().err
    assert "found no evaluate records" in err and "Traceback" not in err
