"""``python -m masp_lite evaluate --method M --scenario S [--set KEY=VALUE ...] [--json PATH]``.

Runs :func:`masp_lite.evaluation.evaluate` and prints the record as the paper's table.
``--set`` takes scenario overrides (``num_agents=100``, ``team_after=none``) and the
method's options (``power=2``), each value parsed by the type of what it sets
(:func:`masp_lite.parsing.parse_sets`, the parser every command uses). The table shows them
beside the method and scenario. ``--json PATH`` is checked to be writable before the run, so
a bad path (in a folder that does not exist, say) fails at once rather than after the whole
evaluation. ``--threads`` is torch's thread count (default :data:`~masp_lite.threads.EVALUATE_THREADS`,
the count every committed record names: a second thread buys nothing for a world's step or a
decision, see :mod:`masp_lite.threads`).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from ..envs import OVERRIDES, SCENARIOS, Scenario, get_scenario
from ..evaluation import MAX_ENVS, evaluate, format_table
from ..files import atomic_write
from ..parsing import parse_sets
from ..policies import get_factory, method_names, method_options, option_types
from ..threads import EVALUATE_THREADS

__all__ = ["add_arguments", "run", "split_sets", "override_types", "check_writable", "check_replaceable",
           "write_record", "EXAMPLES"]

EXAMPLES = [
    "evaluate --method h-greedy --scenario mpe-20 --episodes 100 --seeds 0 1 2 --json out.json",
    "evaluate --method h-greedy --scenario mpe-20to10 --set team_after=none   # overrides and options",
    "evaluate --method masp --scenario mpe-50 --set num_agents=100",
    "evaluate --method masp --scenario mpe-20 --checkpoint runs/mpe-20/weights.pt",
]


def override_types() -> dict[str, object]:
    """``{override: type}`` of the scenario overrides (:data:`~masp_lite.envs.OVERRIDES`: ``Scenario``'s fields)."""
    return dict(OVERRIDES)


def split_sets(items, method: str, scenario: str | Scenario | None = None) -> tuple[dict, dict]:
    """``KEY=VALUE`` strings -> (scenario overrides, method options); a key that is neither fails.

    The options are those of the method's policy for ``scenario``'s world kind (a preset name or a
    :class:`~masp_lite.envs.Scenario`; a name that is no preset leaves the kind open, and the command
    says so when it builds the scenario)."""
    if isinstance(scenario, Scenario):
        kind = scenario.kind
    else:
        kind = None if scenario is None or scenario not in SCENARIOS else SCENARIOS[scenario].kind
    factory = get_factory(method, kind)
    _, var_kw = method_options(factory)
    options = option_types(factory)
    targets = {"scenario override": override_types(), f"option of method {method!r}": options}
    if var_kw:  # the method checks the names of its **options itself
        targets[f"option of method {method!r}"] = _Any(options)
    got = parse_sets(items, targets)
    return got["scenario override"], got[f"option of method {method!r}"]


class _Any(dict):
    """Every key is accepted (type unknown): for a factory that takes ``**options``."""

    def __contains__(self, key):
        return True

    def __getitem__(self, key):
        return self.get(key)


def check_writable(path, flag: str = "--json", example: str = "out.json") -> Path:
    """``path`` as a ``Path`` when the record can be written there later; else one ValueError.

    Nothing is created: ``path`` must be a writable file, or a new file in an existing, writable
    folder. A missing folder is refused, not made: a file option (``evaluate --json``, ``play
    --out``, ``bench ... --json``) writes one file where the user points, as a shell's ``>`` does,
    so a mistyped folder (``/nonexistent/x.json``, a folder at the file system's root) is one
    clear error rather than a new folder tree. Folder options (``train --out``) make their folder.
    A regular file on the way, or ``path`` itself a folder, fails too."""
    if not str(path).strip():
        raise ValueError(f"{flag}: expected a file path such as {example!r}, got an empty string")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{flag} {str(path)!r} is a folder; expected a file path such as {str(path / example)!r}")
    if path.exists():
        if not path.is_file():  # a device (/dev/full) or a pipe would swallow or refuse the record
            raise ValueError(f"{flag} {str(path)!r} is not a regular file; expected a writable file path")
        if not os.access(path, os.W_OK):
            raise ValueError(f"{flag} {str(path)!r}: the file is not writable; expected a writable path")
        return path
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if folder.is_dir() and folder != path.parent:  # the nearest existing folder is not the file's own
        raise ValueError(f"{flag} {str(path)!r}: the folder {str(path.parent)!r} does not exist; expected a file "
                         f"in an existing folder (create the folder first, or write {path.name!r} elsewhere)")
    if not folder.is_dir():
        raise ValueError(f"{flag} {str(path)!r}: {str(folder)!r} is a file, not a folder; expected a writable path")
    probe = folder / f".masp-lite-probe-{os.getpid()}"
    try:  # permissions alone do not tell (/proc, a read-only mount): write a probe file and remove it
        if not os.access(folder, os.W_OK | os.X_OK):
            raise PermissionError
        probe.write_bytes(b"")
        probe.unlink()
    except OSError:
        raise ValueError(f"{flag} {str(path)!r}: the folder {str(folder)!r} is not writable; "
                         f"expected a writable path") from None
    return path


def check_replaceable(path: Path, checkpoint=None) -> None:
    """An existing ``--json`` file may be replaced only when it is an earlier record (or empty), never an input.

    ``evaluate --checkpoint w.pt --json w.pt`` would put the record over the weights it measured; a
    weights file, a notebook or any other file that is not JSON is refused the same way."""
    if not path.is_file():
        return
    if checkpoint is not None and Path(checkpoint).exists() and os.path.samefile(path, checkpoint):
        raise ValueError(f"--json {str(path)!r} is the --checkpoint file; expected another path for the record "
                         "(writing it there would replace the weights)")
    with open(path, "rb") as f:
        head = f.read(64).lstrip()
    if head and not head.startswith(b"{"):
        raise ValueError(f"--json {str(path)!r} holds something other than a JSON record (it starts with "
                         f"{head[:8]!r}); expected a new path or an earlier record to replace")


def write_record(record: dict, path: Path) -> Path:
    """Write ``record`` to ``path``; if that fails after the run, beside the working folder; returns where.

    A finished evaluation is never lost: when ``path`` cannot be written (it changed during the
    run, the disk filled up) the record goes to ``evaluate-METHOD-SCENARIO.json`` in the
    working folder (a numbered name if that exists), and a ValueError says both."""
    text = json.dumps(record, indent=2) + "\n"
    try:
        atomic_write(path, text)  # whole or not at all: a full disk leaves an earlier record as it was
        return path
    except OSError as e:
        reason = e.strerror or type(e).__name__
    stem = f"evaluate-{record['method']}-{record['scenario']}"
    spare = next(p for k in range(10_000) if not (p := Path(f"{stem}{'-' + str(k) if k else ''}.json")).exists())
    try:
        atomic_write(spare, text)
    except OSError:
        print(text)
        raise ValueError(f"--json {str(path)!r}: could not write the record ({reason}), nor a copy in the working "
                         f"folder; it is printed above") from None
    raise ValueError(f"--json {str(path)!r}: could not write the record ({reason}); it was written to "
                     f"{str(spare)!r} instead")


def add_arguments(parser) -> None:
    parser.add_argument("--method", required=True, metavar="METHOD",
                        help=f"one of: {', '.join(method_names())}")
    parser.add_argument("--scenario", required=True, help=f"scenario preset, one of: {', '.join(SCENARIOS)}")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per seed (default 100)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2],
                        help="evaluation seeds, distinct, >= 0 (default 0 1 2: the reported ones; 100+ for "
                             "validation)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override or method option (repeatable)")
    parser.add_argument("--checkpoint", default=None, help="weights for a learned method")
    parser.add_argument("--json", default=None, help="write the result record to this file")
    parser.add_argument("--device", default="cpu", help="torch device (default cpu)")
    parser.add_argument("--threads", type=int, default=EVALUATE_THREADS,
                        help=f"torch threads (default {EVALUATE_THREADS}, as the committed records)")
    parser.add_argument("--num-envs", type=int, default=None, help=f"batch size (default ≤ {MAX_ENVS})")
    parser.add_argument("--format", default="markdown", choices=["markdown", "text", "latex"],
                        help="table format printed on stdout (default markdown)")


def run(args) -> int:
    if args.threads < 1:
        raise ValueError(f"--threads: expected a positive int, got {args.threads}")
    preset = get_scenario(args.scenario)  # the one lookup of the name; evaluate applies the overrides to it
    overrides, options = split_sets(args.set, args.method, preset)
    out = check_writable(args.json) if args.json is not None else None
    torch.set_num_threads(args.threads)
    if out is not None:
        check_replaceable(out, args.checkpoint)
    record = evaluate(args.method, preset, episodes=args.episodes, seeds=args.seeds,
                      overrides=overrides, method_options=options, checkpoint=args.checkpoint,
                      device=args.device, num_envs=args.num_envs, progress=True)
    print(format_table([record], fmt=args.format))
    if out is not None:
        write_record(record, out)
    return 0
