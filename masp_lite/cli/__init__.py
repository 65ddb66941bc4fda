"""Command line: ``python -m masp_lite COMMAND ...`` or ``masp-lite COMMAND ...``, one module per command.

Argparse only. Each command module (:mod:`.evaluate`, :mod:`.train`, :mod:`.play`, :mod:`.reproduce`,
:mod:`.bench`) provides ``add_arguments(parser)`` and ``run(args) -> int`` over the library's public functions,
and may list ``EXAMPLES`` (command lines shown at the end of its ``--help``); this file only
dispatches, so commands stay independent. A ``ValueError`` (bad input) becomes one
``error: ...`` line and exit status 2.

Usage lines name the program as it was started: ``python -m masp_lite evaluate``, or ``masp-lite
evaluate`` for the command ``pip install`` makes (:func:`console`). In a source checkout, examples
are written as the README writes its commands, with the course's environment spelt out
(:data:`PYTHON`, see :data:`ENVIRONMENT`: a bare ``python`` outside that environment has no torch);
an installed copy has no checkout and no ``.venv`` to point to, so its examples use the program's
own name and its help says nothing of the repository.
"""
from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["COMMANDS", "PYTHON", "ENVIRONMENT", "MODULE_PROG", "main", "console", "epilog", "program", "in_checkout"]

#: The course's interpreter, as the README's commands spell it (run from the repository root).
PYTHON = ".venv/bin/python"
#: How to run the commands: the same sentence as the README's.
ENVIRONMENT = (f"Run the commands from the repository root with the course's environment: write `{PYTHON}`, "
               "or run `source .venv/bin/activate` once and then write plain `python`.")

#: command -> (module, one-line help)
COMMANDS = {
    "evaluate": ("masp_lite.cli.evaluate", "evaluate a method on a scenario (SR, Steps, CR, decision time)"),
    "train": ("masp_lite.cli.train", "train a learned method (checkpoints, resume, manifest)"),
    "play": ("masp_lite.cli.play", "record an episode as .gif/.mp4 (2-D) or .html (3-D)"),
    "reproduce": ("masp_lite.cli.reproduce", "the paper's tables, ours beside the paper's"),
    "bench": ("masp_lite.cli.bench", "throughput and latency benchmarks"),
}


#: The program's name when started as ``python -m masp_lite`` (:func:`main`'s default).
MODULE_PROG = "python -m masp_lite"
_prog = MODULE_PROG  # the name of the running program, set by main()


def program() -> str:
    """The running program's name for usage lines: ``python -m masp_lite`` or ``masp-lite``."""
    return _prog


def in_checkout() -> bool:
    """Whether this package runs from a source checkout (its ``pyproject.toml`` beside ``masp_lite/``), where
    the README's ``.venv`` commands apply; False for an installed copy."""
    from ..reproduction import REPO_ROOT  # the one module that knows where a checkout would be
    return (REPO_ROOT / "pyproject.toml").is_file() and (REPO_ROOT / "masp_lite" / "cli").is_dir()


def _example_prefix() -> str:
    return f"{PYTHON} -m masp_lite" if in_checkout() else _prog


def _usage() -> str:
    lines = [f"usage: {_prog} COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", f"{_prog} COMMAND --help shows a command's options.", ""]
    lines += [ENVIRONMENT] if in_checkout() else []
    lines += [f"For example: {_example_prefix()} evaluate --help"]
    return "\n".join(lines)


def epilog(examples=()) -> str:
    """The end of a command's ``--help``: its examples (``"evaluate --method ..."``) and, in a source checkout,
    :data:`ENVIRONMENT`."""
    lines = ["examples:", *(f"  {_example_prefix()} {e}" for e in examples)] if examples else []
    if in_checkout():
        lines += ["", ENVIRONMENT] if lines else [ENVIRONMENT]
    return "\n".join(lines)


def console() -> int:
    """The ``masp-lite`` command that ``pip install`` makes: :func:`main` under that name."""
    return main(prog="masp-lite")


def main(argv: list[str] | None = None, prog: str = MODULE_PROG) -> int:
    """Run one command (``argv``: the command's name and its options; default ``sys.argv[1:]``) as ``prog``."""
    global _prog
    _prog = prog
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"unknown command {name!r}; expected one of {list(COMMANDS)}\n\n{_usage()}", file=sys.stderr)
        return 2
    module_name, help_ = COMMANDS[name]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as e:
        if e.name and e.name.startswith(module_name):
            print(f"command {name!r} is not available in this version ({module_name} is missing)", file=sys.stderr)
            return 2
        raise
    parser = argparse.ArgumentParser(prog=f"{prog} {name}", description=help_,
                                     epilog=epilog(getattr(module, "EXAMPLES", ())),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    module.add_arguments(parser)
    args = parser.parse_args(rest)
    try:
        return int(module.run(args) or 0)
    except ValueError as e:  # bad input: one clear message, no traceback
        print(f"error: {e}", file=sys.stderr)
        return 2

