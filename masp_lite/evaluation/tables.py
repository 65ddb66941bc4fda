"""Paper-format tables of :func:`masp_lite.evaluation.evaluate` records.

Every cell is "mean (std)" with two decimals, as in the paper's tables (a mean just below 1
gets the decimals it needs not to read 1.00: an SR of 0.999 left an episode unsolved); Steps is
a backslash when no episode reached SR 1 (the paper's rule). Plain text, markdown and LaTeX.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["format_table", "cell", "render_rows", "scenario_label", "method_label"]

_METRICS = (("steps", "Steps", r"$\downarrow$", "↓"), ("sr", "SR", r"$\uparrow$", "↑"),
            ("cr", "CR", r"$\downarrow$", "↓"))


def cell(stat, latex: bool = False) -> str:
    """"mean (std)" with 2 decimals from ``{"mean", "std"}`` or ``(mean, std)``; a missing mean is
    the paper's backslash (only Steps has one); no statistic at all (``None``) is "—"."""
    if stat is None:
        return "—"
    mean, std = (stat.get("mean"), stat.get("std")) if isinstance(stat, dict) else stat
    if mean is None:
        return r"$\backslash$" if latex else "\\"
    m = _mean_text(mean)
    if latex:
        return f"{m}\\scriptsize{{({std:.2f})}}"
    return f"{m} ({std:.2f})"


def _mean_text(mean: float) -> str:
    """Two decimals, or as many more as it takes for a mean just below 1 not to read 1.00 (SR 0.999 is not all)."""
    for digits in range(2, 7):
        text = f"{mean:.{digits}f}"
        if not (mean < 1 and float(text) >= 1):
            return text
    return text


def _settings(values: dict) -> str:
    return ", ".join(f"{k}={Path(v).name if k == 'checkpoint' else v}" for k, v in sorted(values.items()))


def scenario_label(record: dict) -> str:
    """The record's scenario with its overrides, as ``evaluate --set`` gave them: "mpe-50 (num_agents=100)"."""
    overrides = record.get("overrides") or {}
    return f"{record['scenario']} ({_settings(overrides)})" if overrides else record["scenario"]


def method_label(record: dict) -> str:
    """The record's method with its options ("h-greedy (power=2)"; a checkpoint by its file name)."""
    options = record.get("method_options") or {}
    return f"{record['method']} ({_settings(options)})" if options else record["method"]


def render_rows(head: list[str], body: list[list[str]], fmt: str) -> str:
    """Rows of cells as ``markdown``, ``text`` (aligned columns) or ``latex`` (a ``tabular``)."""
    if fmt not in ("markdown", "text", "latex"):
        raise ValueError(f"format: expected markdown, text or latex, got {fmt!r}")
    if fmt == "latex":
        esc = lambda c: (c.replace("_", r"\_").replace("↓", r"$\downarrow$").replace("↑", r"$\uparrow$")  # noqa: E731
                         .replace("—", "--"))
        lines = [r"\begin{tabular}{" + "l" * 2 + "c" * (len(head) - 2) + "}", r"\hline",
                 " & ".join(map(esc, head)) + r" \\", r"\hline"]
        lines += [" & ".join(map(esc, row)) + r" \\" for row in body]
        return "\n".join(lines + [r"\hline", r"\end{tabular}"])
    widths = [max(len(c) for c in col) for col in zip(head, *body)]
    if fmt == "text":
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in [head, *body])
    line = lambda row: "| " + " | ".join(c.ljust(w) for c, w in zip(row, widths)) + " |"  # noqa: E731
    return "\n".join([line(head), "|" + "|".join("-" * (w + 2) for w in widths) + "|", *map(line, body)])


def format_table(rows, fmt: str = "markdown", layout: str = "rows") -> str:
    """Records of :func:`evaluate` as a table of "mean (std)" cells with 2 decimals.

    ``layout="rows"``: one row per record — Method, Scenario, Steps ↓, SR ↑, CR ↓ and the
    decision time (ms per step). A record's scenario overrides and method options (``--set``)
    show beside its scenario and method (:func:`scenario_label`, :func:`method_label`), so a
    100-agent run of mpe-50 reads "mpe-50 (num_agents=100)". ``layout="paper"``: the paper's tables — for each scenario
    three rows (Steps, SR, CR) and one column per method. Steps is a backslash when no
    episode reached SR 1, as in the paper. ``fmt``: ``"markdown"``, ``"text"`` (aligned
    columns) or ``"latex"`` (a ``tabular``; stds in ``\\scriptsize``, the backslash as
    ``$\\backslash$``, arrows as ``$\\downarrow$``, as the paper typesets them).
    """
    rows = [rows] if isinstance(rows, dict) else list(rows)
    if fmt not in ("markdown", "text", "latex") or layout not in ("rows", "paper"):
        raise ValueError(f"format_table: expected fmt in ('markdown', 'text', 'latex') and layout in "
                         f"('rows', 'paper'), got {fmt!r}, {layout!r}")
    latex = fmt == "latex"
    name = lambda m: (rf"\textit{{{m[1]}}} {m[2]}" if latex else f"{m[1]} {m[3]}")  # noqa: E731
    try:
        if layout == "rows":
            head = ["Method", "Scenario", *map(name, _METRICS), "Decision (ms)"]
            body = [[method_label(r), scenario_label(r), *(cell(r[m[0]], latex) for m in _METRICS),
                     cell(r["decision_ms"], latex)] for r in rows]
        else:
            methods = list(dict.fromkeys(map(method_label, rows)))
            scenarios = list(dict.fromkeys(map(scenario_label, rows)))
            by_key = {(scenario_label(r), method_label(r)): r for r in rows}
            head = ["Scenario", "Metric", *methods]
            body = [[sc if i == 0 else "", name(m),
                     *(cell(by_key[sc, meth][m[0]], latex) if (sc, meth) in by_key else "" for meth in methods)]
                    for sc in scenarios for i, m in enumerate(_METRICS)]
    except (KeyError, TypeError):
        raise ValueError("format_table: expected evaluate() records with method, scenario, "
                         "steps, sr, cr and decision_ms") from None
    return render_rows(head, body, fmt)
