"""MASP weights files: save, load and the checks every file passes before it is used.

This folder also holds the shipped weights, one file per scenario (``mpe-5.pt``, ...), and
``manifest.json``; and ``methods/``: the seed-0 weights of every other learned method the
method table lists (``methods/METHOD/PRESET.pt``, hashes in ``methods/manifest.json``), so an
installed copy evaluates every method (:func:`method_checkpoint`). That is the package's only data.

A weights file is a ``torch.save`` of plain tensors and numbers (it loads with
``torch.load(..., weights_only=True)``)::

    {"format": FORMAT, "scenario": "mpe-20", "world": {"integration": ..., "landmark_spawn": ...},
     "arch": {...NetConfig fields...},
     "state_dict": {...all four networks...}}

``manifest.json`` lists the shipped files, one entry per scenario: file name, SHA-256,
architecture, training seed, the last training command, environment steps and
wall-clock summed over every stage, and where the whole training history is kept
(``results/training/SCENARIO-seedS.manifest.json`` in the repository: every stage's
command, configuration, machine and curves). :func:`load_weights` refuses (one clear
``ValueError``) a missing, truncated or corrupt file, a file whose hash differs from the
manifest, another architecture, or weights trained for another scenario; and before anything
is allocated, a file that could exhaust memory: over :data:`MAX_WEIGHTS_BYTES`, not a regular
file, compressed entries (a deflate bomb), a tensor that claims more elements than its bytes
(stride 0), architecture settings beyond :data:`ARCH_BOUNDS`, or tensors that are not real
floating point (never cast). Scenarios with a
team change, or with overrides such as ``num_agents=100``, use the weights of the preset
they start from (``mpe-20to10`` -> ``mpe-20``): the networks are size-invariant, and
this is the paper's zero-shot protocol. A manifest entry may also ship another preset's
file for a preset or a team change, zero-shot (``"trained_on": "mpe-20"`` under
``mpe-50to20``, chosen on validation layouts; its ``note`` says why): such an entry has no
training of its own, and :func:`trained_preset` names the preset whose training seeds stand
for it. A scenario's own entry comes before the one of the preset it starts from
(:func:`shipped_entry`).
"""
from __future__ import annotations

import io
import json
import re
import textwrap
import zipfile
from pathlib import Path

import torch

from ..envs.scenarios import MPE2_WORLD, STARTS_FROM, get_scenario, world_name
from ..files import atomic_write, file_bytes, read_bounded, sha256
from ..nets.masp import MASPNets

__all__ = ["FORMAT", "HERE", "MANIFEST", "METHODS_DIR", "save_weights", "load_weights", "read_weights",
           "read_manifest", "trained_world", "method_checkpoint", "packaged_preset",
           "default_checkpoint", "base_scenario", "shipped_entry", "trained_preset", "weights_bytes"]

FORMAT = "masp-lite/masp-weights/1"
HERE = Path(__file__).resolve().parent
MANIFEST = HERE / "manifest.json"
#: The packaged seed-0 weights of the learned methods other than the shipped MASP (``METHOD/PRESET.pt``).
METHODS_DIR = HERE / "methods"
_ZIP_MAGIC, _PICKLE_MAGIC = b"PK", b"\x80"  # torch.save's zip archive; its legacy pickle format
#: The largest weights file read (the shipped ones are about 0.2 MB): checked before anything is loaded.
MAX_WEIGHTS_BYTES = 64 * 2**20
_READ = (MAX_WEIGHTS_BYTES, "weights file")  # how a weights file is read (files.file_bytes, files.sha256)
#: The largest value of each architecture setting a weights file may declare, checked before any network
#: is built (the shipped networks: width 32, one GCN layer, groups of 3): larger ones would take gigabytes.
ARCH_BOUNDS = {"width": 1024, "group_size": 64, "gcn_layers": 16, "obstacles_seen": 64, "global_step": 1000,
               "neighbours_seen": 64, "team_size": 4096}
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: How to use weights trained elsewhere anyway, in both spellings: the one of the command line and Python's.
_ANYWAY = "to use them anyway: --set any_scenario=true on the command line, any_scenario=True in Python"


def base_scenario(scenario) -> str:
    """The preset whose weights a scenario uses: its own name, or the N1 preset of a team change."""
    name = scenario if isinstance(scenario, str) else scenario.name
    return STARTS_FROM.get(name, name)


def shipped_entry(scenario) -> dict | None:
    """The manifest entry of the weights shipped for ``scenario``: its own (a team change may have
    one), else that of :func:`base_scenario`; ``None`` when nothing ships for it."""
    name = scenario if isinstance(scenario, str) else scenario.name
    manifest = read_manifest()
    return manifest.get(name, manifest.get(base_scenario(name)))


def trained_preset(scenario) -> str:
    """The preset the shipped weights for ``scenario`` were trained on: :func:`base_scenario`,
    or the ``trained_on`` of its manifest entry when another preset's file ships zero-shot."""
    return (shipped_entry(scenario) or {}).get("trained_on", base_scenario(scenario))


def weights_bytes(path) -> bytes:
    """A weights file's bytes (at most :data:`MAX_WEIGHTS_BYTES`), read once while it is unchanged
    (:func:`masp_lite.files.file_bytes`): its hash, its check and its load share them."""
    return file_bytes(path, *_READ)


def save_weights(path, nets, scenario) -> None:
    """Save ``nets`` (a :class:`~masp_lite.nets.masp.MASPNets`) atomically as a weights file.

    ``scenario``: the :class:`~masp_lite.envs.Scenario` trained on (its preset and world
    definition are stored), or a preset name (the preset's own world)."""
    buf = io.BytesIO()
    torch.save({"format": FORMAT, "scenario": base_scenario(scenario), "world": _world(scenario),
                "arch": dict(nets.arch),
                "state_dict": {k: v.detach().cpu().clone() for k, v in nets.state_dict().items()}}, buf)
    atomic_write(path, buf.getvalue())


def _world(scenario) -> dict:
    return (get_scenario(scenario) if isinstance(scenario, str) else scenario).world


def trained_world(record: dict) -> dict:
    """The world definition a weights file was trained in (files without one: mpe2's world)."""
    return dict(record.get("world", MPE2_WORLD))


def read_manifest() -> dict:
    """The shipped weights' manifest: ``{scenario: entry}``."""
    if not MANIFEST.exists():
        return {}
    return json.loads(MANIFEST.read_text())


def _methods_manifest() -> dict:
    path = METHODS_DIR / "manifest.json"
    return json.loads(path.read_text()) if path.exists() else {}


def packaged_preset(scenario, presets) -> str | None:
    """Which of a method's trained ``presets`` its packaged weights for ``scenario`` come from (the rule of
    :func:`method_checkpoint`); None when none fits."""
    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    names = [sc.name, base_scenario(sc), f"{'drone' if sc.kind == 'drone' else 'mpe'}-{sc.num_agents}"]
    return next((n for n in names if n in presets), presets[0] if len(presets) == 1 else None)


def method_checkpoint(method: str, scenario, presets) -> Path:
    """The packaged seed-0 weights of ``method`` for a scenario, among the ``presets`` it was trained on.

    The scenario's own preset, else the preset it starts from (``mpe-20to10`` -> ``mpe-20``), else its
    team size's (``mpe-N``); a method trained on one preset only (the ablations, ``mpe-20``) uses that one."""
    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    entry = _methods_manifest().get(method, {}).get(packaged_preset(sc, presets))
    if entry is None:
        raise ValueError(f"{method}: no weights given and none packaged for {sc.name!r} (packaged: "
                         f"{sorted(_methods_manifest().get(method, {}))}); pass checkpoint=PATH")
    return METHODS_DIR / entry["file"]


def default_checkpoint(scenario) -> Path:
    """The shipped weights file for ``scenario``; a clear error when none is shipped."""
    name = base_scenario(scenario)
    entry = shipped_entry(scenario)
    if entry is None:
        raise ValueError(f"masp: no shipped weights for scenario {name!r}; expected one of "
                         f"{sorted(read_manifest())} or a --checkpoint PATH")
    return HERE / entry["file"]


def _reason(error: Exception, width: int = 200) -> str:
    """The first sentence of torch's message that says what went wrong, shortened at a word boundary.

    ``weights_only`` refusals are a paragraph of advice whose last line names the object
    refused ("WeightsUnpickler error: Unsupported global: ..."): that line is the reason."""
    lines = [line.strip() for line in _ANSI.sub("", str(error)).splitlines() if line.strip()]
    picked = next((line for line in lines if line.startswith("WeightsUnpickler error")), lines[0] if lines else "")
    return textwrap.shorten(picked.split(". ")[0], width, placeholder=" ...") or "no message"


def read_weights(path) -> dict:
    """Load and validate the raw record of a weights file (no networks built).

    A file that is not one says what it is instead: a training state (``state.pt`` of a run
    folder: pass the ``weights.pt`` beside it), not a torch file at all, empty, truncated,
    or holding Python objects that ``torch.load(weights_only=True)`` refuses.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"checkpoint {str(path)!r}: expected an existing weights file")
    packaged = {HERE / v["file"]: v for v in read_manifest().values()}
    packaged.update({METHODS_DIR / v["file"]: v for m in _methods_manifest().values() for v in m.values()})
    entry = packaged.get(path.resolve())
    if entry is not None and sha256(path, *_READ) != entry["sha256"]:
        raise ValueError(f"checkpoint {str(path)!r}: contents differ from manifest.json (corrupt or replaced)")
    run = _run_manifest(path)
    if run is not None and sha256(path, *_READ) != run["weights_sha256"]:
        raise ValueError(f"checkpoint {str(path)!r}: contents differ from the SHA-256 its run recorded in "
                         f"{str(path.parent / 'manifest.json')!r} (corrupt or replaced)")
    data = weights_bytes(path)
    head = data[:4]
    if not head:
        raise ValueError(f"checkpoint {str(path)!r}: the file is empty; expected a MASP weights file")
    if head.startswith(_PICKLE_MAGIC):
        raise ValueError(f"checkpoint {str(path)!r}: saved in torch's legacy (pre-1.6) format, whose declared sizes "
                         "cannot be checked before loading; expected torch.save's zip archive (load it in a trusted "
                         "session and save it again)")
    if not head.startswith(_ZIP_MAGIC):
        raise ValueError(f"checkpoint {str(path)!r}: not a torch file (it starts with {head!r}); expected a MASP "
                         "weights file saved by torch.save, such as a run's weights.pt")
    _check_archive(path, data)
    try:
        rec = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as e:  # truncated zip, objects weights_only refuses, ...
        raise ValueError(f"checkpoint {str(path)!r}: expected a MASP weights file, could not read it "
                         f"({type(e).__name__}: {_reason(e)})") from None
    if isinstance(rec, dict) and {"nets", "iterations"} <= set(rec):
        raise ValueError(f"checkpoint {str(path)!r}: this is a training state (a run's state.pt, for --resume); "
                         "pass the run's weights.pt (in the same folder)")
    if not isinstance(rec, dict) or rec.get("format") != FORMAT:
        raise ValueError(f"checkpoint {str(path)!r}: expected format {FORMAT!r}, got "
                         f"{rec.get('format') if isinstance(rec, dict) else type(rec).__name__!r}")
    _check_record(path, rec)
    return rec


def _check_archive(path: Path, data: bytes) -> None:
    """Refuse a zip archive that would unpack to more than the file holds (a deflate bomb) before torch reads it.

    ``torch.save`` stores every entry uncompressed, so each entry's size is at most the file's; torch
    itself refuses a tensor storage that declares more bytes than its entry has."""
    try:
        entries = zipfile.ZipFile(io.BytesIO(data)).infolist()
    except (zipfile.BadZipFile, ValueError, OSError):
        return  # truncated or damaged: torch's reader says why (it reads nothing of such an archive)
    for e in entries:
        if e.compress_type != zipfile.ZIP_STORED or e.file_size > len(data):
            raise ValueError(f"checkpoint {str(path)!r}: entry {e.filename!r} is compressed ({e.file_size:,} bytes "
                             f"unpacked from {e.compress_size:,}); expected torch.save's uncompressed archive")


def _check_record(path: Path, rec: dict) -> None:
    """The fields of a weights record, each of its type, and every tensor a dense, finite, floating-point
    one of the size its bytes hold (a stride-0 tensor of 10**9 elements on one number is refused before
    anything reads it)."""
    for key, typ, what in (("scenario", str, "a preset name"), ("arch", dict, "a dict of NetConfig settings"),
                           ("state_dict", dict, "a dict of tensors")):
        if not isinstance(rec.get(key), typ):
            got = "missing" if key not in rec else f"a {type(rec[key]).__name__}"
            raise ValueError(f"checkpoint {str(path)!r}: field {key!r} is {got}; expected {what}")
    if not isinstance(rec.get("world", {}), dict):
        raise ValueError(f"checkpoint {str(path)!r}: field 'world' is a {type(rec['world']).__name__}; "
                         "expected a dict (the world definition)")
    for name, t in rec["state_dict"].items():
        where = f"checkpoint {str(path)!r}: state_dict entry {name!r}"
        if not isinstance(name, str) or not isinstance(t, torch.Tensor):
            raise ValueError(f"{where} is a {type(t).__name__}; expected a tensor under a parameter name")
        if not t.dtype.is_floating_point:
            raise ValueError(f"{where} is {t.dtype}; expected floating-point weights (they are not cast)")
        if t.layout != torch.strided or not t.is_contiguous() or \
                t.untyped_storage().nbytes() < (t.storage_offset() + t.numel()) * t.element_size():
            raise ValueError(f"{where} has shape {tuple(t.shape)} and strides {t.stride()}, more elements than its "
                             "stored bytes; expected a dense tensor as torch.save writes a parameter")
    for name, t in rec["state_dict"].items():
        if not bool(torch.isfinite(t).all()):
            raise ValueError(f"checkpoint {str(path)!r}: parameter {name!r} holds NaN or inf; expected finite weights")


def check_arch(arch: dict, path) -> None:
    """Refuse architecture settings beyond :data:`ARCH_BOUNDS` before a network is built from them."""
    for key, high in ARCH_BOUNDS.items():
        v = arch.get(key)
        if isinstance(v, int) and not isinstance(v, bool) and v > high:
            raise ValueError(f"checkpoint {str(path)!r}: arch field {key!r} is {v}; expected at most {high} "
                             "(larger networks than any masp-lite trains)")


def _run_manifest(path: Path) -> dict | None:
    """The manifest of the finished training run whose ``weights.pt`` is ``path``, when it records a hash."""
    manifest = path.parent / "manifest.json"
    if path.name != "weights.pt" or not manifest.is_file():
        return None
    try:
        m = json.loads(read_bounded(manifest, what="run manifest"))
    except (ValueError, OSError, RecursionError):
        return None
    return m if isinstance(m, dict) and isinstance(m.get("weights_sha256"), str) else None


def load_weights(path=None, scenario=None, any_scenario: bool = False):
    """Build :class:`~masp_lite.nets.masp.MASPNets` from a weights file; returns ``(nets, record)``.

    ``path`` ``None`` means the shipped file for ``scenario``. Unless ``any_scenario``,
    the file must have been trained for ``base_scenario(scenario)`` (or for the preset whose
    weights ship for it zero-shot, :func:`trained_preset`), in the scenario's world
    definition (update order, landmark spawn; :func:`trained_world`).
    """
    if path is None:
        if scenario is None:
            raise ValueError("load_weights: expected a path or a scenario")
        path = default_checkpoint(scenario)
    rec = read_weights(path)
    check_arch(rec["arch"], path)
    kind = "drone" if rec["arch"].get("action", "discrete") != "discrete" else "particle"
    want = None if scenario is None else (get_scenario(scenario) if isinstance(scenario, str) else scenario).kind
    if want is not None and kind != want:
        raise ValueError(f"checkpoint {str(path)!r} holds {kind}-world networks (action "
                         f"{rec['arch'].get('action', 'discrete')!r}); expected weights for the {want} world of "
                         f"{scenario if isinstance(scenario, str) else scenario.name!r}")
    if scenario is not None and not any_scenario and rec["scenario"] not in (base_scenario(scenario),
                                                                             trained_preset(scenario)):
        raise ValueError(f"checkpoint {str(path)!r} was trained for {rec['scenario']!r}; expected weights for "
                         f"{base_scenario(scenario)!r} ({_ANYWAY})")
    if scenario is not None and not any_scenario and not isinstance(scenario, str) and \
            trained_world(rec) != scenario.world:
        raise ValueError(f"checkpoint {str(path)!r} was trained in the world {world_name(trained_world(rec))}; "
                         f"expected weights for {world_name(scenario.world)} ({_ANYWAY})")
    try:
        if kind == "drone":
            from ..nets.drones import DroneNets  # MuJoCo only for drone weights
        nets = (DroneNets if kind == "drone" else MASPNets)(**rec["arch"])
        own = nets.state_dict()
        for name, t in rec["state_dict"].items():
            if name in own and t.dtype != own[name].dtype:
                raise ValueError(f"parameter {name!r} is {t.dtype}, the networks' is {own[name].dtype}")
        nets.load_state_dict(rec["state_dict"])
    except (TypeError, ValueError, RuntimeError, KeyError) as e:
        raise ValueError(f"checkpoint {str(path)!r}: architecture does not match MASPNets "
                         f"({type(e).__name__}: {_reason(e)})") from None
    return nets, rec
