"""The paper's tables from our evaluation records, ours beside the paper's numbers.

Each table is one small function of the records (``table_mpe``, ``table_mpe_varying``,
``table_time``) that returns a :class:`Table`; :func:`render` prints it as text, markdown
or LaTeX in the paper's layout — for each team size three metric rows, and for each row
our number above the paper's. A cell that has no record shows "—"; a Steps mean of
``None`` is the paper's backslash.

Records come from ``results/`` of a source checkout (:func:`load_records`), or from
:func:`evaluate_records` (``reproduce --evaluate``: the registered methods with their
shipped weights, or ``--quick``: a few episodes per seed). A table takes only records made
in its presets' world definition (:attr:`masp_lite.envs.Scenario.world`) and says which
world that is, so numbers from two worlds are never mixed in one table. Methods of the
paper without a record in a cell (a method not evaluated there, or whose weights this checkout
lacks) show "—" in our rows.

A learned method's cell is the mean over its training seeds when records of several are
there (the shipped weights and ``results/training/BASE-seedK.pt``, see :func:`pick`); a
note under the table says which seeds.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import torch

from ..envs import MPE2_WORLD, SCENARIOS, get_scenario, world_name
from ..evaluation import evaluate
from ..evaluation.tables import cell, render_rows
from ..files import read_bounded
from ..policies import METHODS
from ..weights import base_scenario, read_manifest, shipped_entry, trained_preset
from . import RESULTS_DIR
from .paper import PAPER

__all__ = ["Table", "TABLES", "PAPER", "RESULTS_DIR", "load_records", "validate_record", "re_evaluate",
           "re_evaluation_cost_s", "pick", "pool",
           "training_seed", "fill_blocks", "text_legend",
           "evaluation_jobs", "evaluate_records", "render", "build"]

_MPE_COLUMNS = ("h-orca", "h-rrtstar", "h-voronoi", "h-mappo", "mappo", "darl1n", "htamp", "mage-x", "masp")
_RL = ("h-mappo", "mappo", "darl1n", "htamp", "mage-x")
"""The RL baselines: their cells are their kept training seeds, ``results/training/METHOD/``."""
_OURS_ONLY = ("h-greedy", "h-capt", "h-bottleneck")
_LABEL = {"h-orca": "(H)ORCA", "h-rrtstar": "(H)RRT*", "h-voronoi": "(H)Voronoi", "h-mappo": "(H)MAPPO",
          "mappo": "MAPPO", "darl1n": "DARL1N", "htamp": "HTAMP", "mage-x": "MAGE-X", "masp": "MASP",
          "h-greedy": "h-greedy", "h-capt": "h-capt", "h-bottleneck": "h-bottleneck"}


@dataclass
class Table:
    """One paper table: a title, the world its records come from, a header and rows of cells."""

    name: str
    title: str
    world: dict
    head: list
    rows: list
    notes: list = field(default_factory=list)
    """Lines printed under the table (e.g. which training seeds a learned method's cells pool)."""




def load_records(root=RESULTS_DIR) -> list[dict]:
    """Every ``evaluate --json`` record under ``root`` (default :data:`RESULTS_DIR`), each with its ``path``.

    ``bench planners --json`` files count too: each method's one-world step time becomes a
    record with ``num_envs`` 1 and only ``decision_ms`` (what the per-step-time table reads), in
    the world the file names (files that name none were made in mpe2's world)."""
    root = Path(root)
    if not root.is_dir():
        where = " (the records are a source checkout's: this copy of masp_lite is installed without them; " \
            "pass --records DIR)" if root == RESULTS_DIR else ""
        raise ValueError(f"records: expected a folder of evaluate records such as results/, got {str(root)!r}{where}")
    out = []
    for path in _json_files(root):
        data = read_bounded(path, MAX_RECORD_BYTES, "JSON evaluation record")  # a FIFO or a device: refused
        try:
            rec = json.loads(data)
        except (ValueError, UnicodeDecodeError, RecursionError) as e:  # empty, truncated, binary or nested too deep
            reason = "nested too deep" if isinstance(e, RecursionError) else str(e)
            raise ValueError(f"{path}: expected a JSON evaluation record, could not parse it ({reason})") from None
        if not isinstance(rec, dict):
            raise ValueError(f"{path}: expected a JSON object (an evaluation record), got a {type(rec).__name__}")
        if "method" in rec and ({"seeds", "sr", "steps", "episodes_per_seed"} & set(rec)):  # meant as a record
            out.append({**validate_record(rec, path), "path": str(path)})
        elif isinstance(rec, dict) and "scenario" in rec and rec.get("episodes"):  # a bench planners record
            for method, v in rec.items():
                if isinstance(v, dict) and "ms" in v:
                    out.append({"method": method, "scenario": rec["scenario"], "num_envs": 1, "bench": True,
                                "world": rec.get("world", MPE2_WORLD),
                                "decision_ms": v["ms"], "path": str(path)})
    return out


#: The largest record read (a record is about a kilobyte).
MAX_RECORD_BYTES = 4 * 2**20


def _json_files(root: Path) -> list[Path]:
    """Every ``*.json`` file under ``root``, through linked subfolders too (each real folder once), sorted.

    A folder named ``x.json`` is walked into, not read; a link to nothing is kept, and refused by name."""
    seen, found = set(), []
    for folder, dirs, files in os.walk(root, followlinks=True):
        real = os.path.realpath(folder)
        if real in seen:  # a link back up: walked already
            dirs[:] = []
            continue
        seen.add(real)
        found += [Path(folder) / f for f in files if f.endswith(".json")]
    return sorted(found)


_STATS = ("sr", "steps", "cr", "decision_ms")


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def validate_record(rec, path) -> dict:
    """``rec`` when it is a well-formed ``evaluate`` record of a known method and preset; else one ValueError.

    Checked: the keys, their types, the ranges (SR in [0, 1], Steps in [0, horizon] or ``None``
    when nothing was solved, CR and decision time >= 0, standard deviations >= 0, all finite),
    seeds (distinct ints >= 0), episodes, and the world the record names against the one its
    scenario and overrides make. The error names the file and the field."""
    def bad(field_, expected, got):
        raise ValueError(f"{path}: field {field_!r}: expected {expected}, got {got!r}")

    if not isinstance(rec, dict):
        bad("(top level)", "a JSON object (an evaluate record)", type(rec).__name__)
    for key in ("method", "scenario", "world", "seeds", "episodes_per_seed", *_STATS):
        if key not in rec:
            bad(key, "present (an evaluate record has method, scenario, world, seeds, episodes_per_seed, "
                     "sr, steps, cr, decision_ms)", None)
    for key in ("method", "scenario"):
        if not isinstance(rec[key], str):
            bad(key, "a name (a string)", rec[key])
    if rec["method"] not in METHODS:
        bad("method", f"one of {sorted(METHODS)}", rec["method"])
    overrides = rec.get("overrides", {})
    if not isinstance(overrides, dict):
        bad("overrides", "an object of scenario overrides", overrides)
    try:
        sc = get_scenario(rec["scenario"], **overrides)
    except (ValueError, TypeError) as e:
        bad("scenario", "a known preset with valid overrides", f"{rec['scenario']} ({e})")
    if rec["world"] != sc.world:
        bad("world", f"the world its scenario and overrides make, {sc.world}", rec["world"])
    seeds = rec["seeds"]
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and not isinstance(s, bool)
                                                            and s >= 0 for s in seeds) or len(set(seeds)) < len(seeds):
        bad("seeds", "a non-empty list of distinct ints >= 0", seeds)
    n = rec["episodes_per_seed"]
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        bad("episodes_per_seed", "a positive int", n)
    ranges = {"sr": (0.0, 1.0), "steps": (0.0, float(sc.horizon)), "cr": (0.0, math.inf),
              "decision_ms": (0.0, math.inf)}
    for key, (lo, hi) in ranges.items():
        stat = rec[key]
        if not isinstance(stat, dict) or set(stat) != {"mean", "std"}:
            bad(key, '{"mean": number, "std": number}', stat)
        if key == "steps" and stat["mean"] is None and stat["std"] is None:
            continue  # no episode reached SR 1: the paper's backslash
        if not _number(stat["mean"]) or not lo <= stat["mean"] <= hi:
            bad(f"{key}.mean", f"a finite number in [{lo:g}, {hi:g}]", stat["mean"])
        if not _number(stat["std"]) or stat["std"] < 0:
            bad(f"{key}.std", "a finite number >= 0", stat["std"])
    return rec


ENV_S_PER_AGENT = 1e-5
"""The world's own cost per agent and world-step, batched (a rough figure for a laptop CPU)."""


def re_evaluation_cost_s(rec: dict) -> float:
    """Seconds re-evaluating a record takes, roughly: the recorded decision time plus the world's, every world-step."""
    sc = get_scenario(rec["scenario"], **rec.get("overrides", {}))
    per_step = rec["decision_ms"]["mean"] / 1e3 + ENV_S_PER_AGENT * sc.num_agents
    return per_step * rec["episodes_per_seed"] * len(rec["seeds"]) * sc.horizon


def re_evaluate(rec: dict) -> dict:
    """``rec`` evaluated again exactly as it was made: its world definition, seeds, episodes, batch size,
    overrides, options, weights file (paths relative to the working folder) and torch thread count.

    Returns the new record, whose ``overrides`` are the record's own (the world definition is
    passed only to rebuild the world it was made in)."""
    options = dict(rec.get("method_options", {}))
    checkpoint = options.pop("checkpoint", None)  # a record keeps it among the options; evaluate takes it apart
    threads = torch.get_num_threads()
    torch.set_num_threads(rec.get("threads", threads))  # a float sum's rounding depends on it
    try:
        new = evaluate(rec["method"], rec["scenario"], episodes=rec["episodes_per_seed"], seeds=rec["seeds"],
                       overrides={**rec["world"], **rec.get("overrides", {})}, method_options=options,
                       checkpoint=checkpoint, num_envs=rec.get("num_envs"))
    finally:
        torch.set_num_threads(threads)
    new.pop("overrides", None)
    return {**new, **({"overrides": rec["overrides"]} if "overrides" in rec else {})}


def _preset_batched(rec: dict) -> bool:
    """No overrides beyond the world definition, evaluated in batches (a record of one world at a
    time, ``num_envs`` 1, is a timing record that only the per-step-time table reads)."""
    extra = set(rec.get("overrides", {})) - {"integration", "landmark_spawn"}
    return not extra and not rec.get("bench") and rec.get("num_envs") != 1


def _plain(rec: dict) -> bool:
    """A record of the method as shipped: no options, the preset, batched."""
    return not rec.get("method_options") and _preset_batched(rec)


def training_seed(rec: dict, kept: str = "") -> int | None:
    """The training seed behind a learned method's record, or None for anything else.

    A record of the shipped weights (no options) is the shipped file's seed (the manifest's;
    0 when nothing is shipped); a record whose only option is ``checkpoint`` =
    ``results/training/BASE-seedK.pt`` (the kept weights of training seed K of the scenario's
    preset, or of the preset whose weights it runs zero-shot: :func:`masp_lite.weights.trained_preset`)
    is K. With ``kept`` (a folder under ``results/training/``, e.g. ``"faithful/"``), only
    ``results/training/KEPT/PRESET-seedK.pt`` counts: the training seeds of another recipe, whose
    weights of any preset may run here with ``any_scenario`` (the faithful recipe trains mpe-20 and
    runs mpe-50 zero-shot, where the shipped chain trains at N = 50)."""
    opts = rec.get("method_options", {})
    if not _preset_batched(rec):
        return None
    if not opts:
        return None if kept else int((shipped_entry(rec["scenario"]) or {}).get("seed", 0))
    m = re.fullmatch(r"results/training/(.+)-seed(\d+)\.pt", str(opts.get("checkpoint", "")))
    if kept:  # another recipe: weights of any preset, run here with any_scenario
        presets, allowed = {kept + name for name in SCENARIOS}, {"checkpoint", "any_scenario"}
    else:
        presets, allowed = {trained_preset(rec["scenario"]), base_scenario(rec["scenario"])}, {"checkpoint"}
    if m and m.group(1) in presets and set(opts) <= allowed and opts.get("any_scenario", True) is True:
        return int(m.group(2))
    return None


def _learned(method: str) -> bool:
    """A method that loads weights (networks in the method table)."""
    return method in METHODS and any("nets" in e for e in METHODS[method].values())


def pool(records) -> dict:
    """One record from several with the same seeds and episodes (e.g. one per training seed).

    Means are the mean of the records' means; standard deviations are over all their
    episodes pooled (population std, as :func:`~masp_lite.evaluation.evaluate` reports
    one record's). A Steps ``None`` (no episode solved) counts as the horizon, which is what
    every one of its episodes scored."""
    first = records[0]
    if any((r["seeds"], r["episodes_per_seed"]) != (first["seeds"], first["episodes_per_seed"]) for r in records):
        raise ValueError("pool: expected records with the same seeds and episodes per seed")
    out = {k: first[k] for k in ("method", "scenario", "world", "seeds", "episodes_per_seed")}
    horizon = get_scenario(first["scenario"]).horizon
    for key in ("sr", "steps", "cr"):
        stats = [r[key] if r[key]["mean"] is not None else {"mean": horizon, "std": 0.0} for r in records]
        mean = sum(x["mean"] for x in stats) / len(stats)
        second = sum(x["std"] ** 2 + x["mean"] ** 2 for x in stats) / len(stats)
        out[key] = {"mean": mean, "std": max(second - mean**2, 0.0) ** 0.5}
    if all(r["steps"]["mean"] is None for r in records):
        out["steps"] = {"mean": None, "std": None}
    out["pooled"] = [r.get("path") for r in records]
    return out


def pick(records, method: str, scenario: str, kept: str = "", seeds=None) -> dict | None:
    """The record of ``method`` on the preset ``scenario`` in the preset's world, or None.

    A record from another world definition is never taken; two candidates are one clear
    error (the table would otherwise depend on file order). A learned method's records of
    several training seeds (:func:`training_seed`) are pooled into one (:func:`pool`), with
    ``training_seeds`` saying which. ``kept`` picks the training seeds of another recipe
    (see :func:`training_seed`); then only those records count. ``seeds`` keeps only those
    training seeds (None: all)."""
    world = get_scenario(scenario).world
    mine = [r for r in records if r["method"] == method and r["scenario"] == scenario and r.get("world", {}) == world]
    by_seed = {}
    if _learned(method):
        for r in mine:
            k = training_seed(r, kept)
            if k is not None and (seeds is None or k in seeds):
                by_seed.setdefault(k, []).append(r)
    groups = list(by_seed.values()) if by_seed or kept or seeds is not None else [[r for r in mine if _plain(r)]]
    for found in groups:
        if len(found) > 1:
            raise ValueError(f"reproduce: {len(found)} records of {method} on {scenario}: "
                             f"{[r.get('path') for r in found]}; expected one")
    if len(by_seed) > 1 or ((kept or seeds is not None) and by_seed):
        return {**pool([by_seed[k][0] for k in sorted(by_seed)]), "training_seeds": sorted(by_seed)}
    return groups[0][0] if groups and groups[0] else None


def _common_seeds(records, scenario, columns):
    """The training seeds that every column with kept seeds has (None when no column has any)."""
    have = [set(r["training_seeds"]) for _, m, kept in columns if kept
            for r in [pick(records, m, scenario, kept)] if r is not None]
    return set.intersection(*have) if have else None


def _metric_table(name, title, scenarios, columns, records, latex, paper=None, matched=False):
    """Three metric rows per scenario, ours above the paper's, one column per ``(label, method, kept)``.

    ``kept`` picks a recipe's kept training seeds (:func:`pick`); ``paper(scenario, i)`` is
    column ``i``'s paper cell, or None (default: ``PAPER[name][(scenario, method)]``; ``False``: no paper
    rows, for a table beyond the paper). With
    ``matched``, the kept-seed columns pool only the training seeds all of them have, so that
    a variant trained with seed 0 alone is compared with MASP's seed 0, not with a mean over
    seeds it lacks."""
    if paper is False:  # a table with no paper row (beyond the paper)
        paper = None
    else:
        paper = paper or (lambda sc, i: PAPER[name].get((sc, columns[i][1])))
    head = ["Agents", "Metric", "", *(c[0] for c in columns)]
    rows, notes = [], []
    for sc in scenarios:
        common = _common_seeds(records, sc, columns) if matched else None
        ours = [pick(records, m, sc, kept, common if kept else None) for _, m, kept in columns]
        theirs = [paper(sc, i) for i in range(len(columns))] if paper is not None else []
        for i, (key, label) in enumerate((("steps", "Steps ↓"), ("sr", "SR ↑"), ("cr", "CR ↓"))):
            rows.append([sc if i == 0 else "", label, "ours",
                         *(cell(r[key], latex) if r else "—" for r in ours)])
            if paper is not None:
                rows.append(["", "", "paper", *(cell(p[key], latex) if p else "" for p in theirs)])
        notes += [f"{sc}, {label}: mean over training seeds {', '.join(map(str, r['training_seeds']))}"
                  for (label, _, _), r in zip(columns, ours) if r and "training_seeds" in r]
    return Table(name, title, get_scenario(scenarios[0]).world, head, rows, notes)


def _columns(methods):
    return [(_LABEL[m], m, f"{m}/" if m in _RL else "") for m in methods]


def table_mpe(records, latex=False) -> Table:
    """Table "MPE" (fixed teams, N = 5, 20, 50): the paper's columns, then our extra baselines.

    MASP is the shipped MASP; the RL baselines are their kept seeds, trained at each team size
    with the budget of "MASP (budget)": MASP from random networks with the same recipe and
    env steps at each team size (``results/training/masp-budget/``)."""
    columns = _columns(_MPE_COLUMNS) + [("MASP (budget)", "masp", "masp-budget/")] + _columns(_OURS_ONLY)
    return _metric_table("mpe", "MPE, N = 5 / 20 / 50", ("mpe-5", "mpe-20", "mpe-50"), columns, records, latex,
                         paper=lambda sc, i: PAPER["mpe"].get((sc, columns[i][1])) if i < len(_MPE_COLUMNS) else None)


def table_mpe_varying(records, latex=False) -> Table:
    """Table "MPE, varying team size" (20 => 10, 50 => 20)."""
    return _metric_table("mpe-varying", "MPE, varying team size", ("mpe-20to10", "mpe-50to20"),
                         _columns(("h-orca", "h-rrtstar", "h-voronoi", "masp") + _OURS_ONLY), records, latex)


#: The drone variant of MASP whose executor asks the geometric controller for a velocity: a column of its
#: kept training seeds (``results/training/masp-velocity/``), beside the paper's columns.
_VELOCITY = ("MASP (velocity)", "masp-velocity", "masp-velocity/")


def table_omnidrones(records, latex=False) -> Table:
    """Table "OmniDrones" (N = 5, 20): the paper's columns, then ours only: MASP whose executor asks the
    geometric controller for a velocity (``masp-velocity``), h-greedy and h-bottleneck. MASP pools the
    shipped weights and the kept training seeds (``results/training/drone-N-seedK.pt``); the RL
    baselines and ``masp-velocity`` are their kept training seeds, trained with MASP's drone budget."""
    methods = ("h-orca", "h-rrtstar", "h-voronoi", *_RL, "masp")
    columns = _columns(methods) + [_VELOCITY] + _columns(("h-greedy", "h-bottleneck"))
    return _metric_table("omnidrones", "OmniDrones, N = 5 / 20", ("drone-5", "drone-20"), columns, records, latex,
                         paper=lambda sc, i: PAPER["omnidrones"].get((sc, columns[i][1])) if i < len(methods)
                         else None)


def table_omnidrones_varying(records, latex=False) -> Table:
    """Table "OmniDrones, varying team size" (20 => 10, zero-shot from the drone-20 weights)."""
    columns = [*_columns(("h-orca", "h-rrtstar", "h-voronoi", "masp")), _VELOCITY,
               *_columns(("h-greedy", "h-bottleneck"))]
    return _metric_table("omnidrones-varying", "OmniDrones, varying team size", ("drone-20to10",), columns, records,
                         latex, paper=lambda sc, i: PAPER["omnidrones-varying"].get((sc, columns[i][1])))


def table_time(records, latex=False) -> Table:
    """Table "per-step time": ms per step of one world at N = 50 (``bench planners`` / ``bench decide``).

    Ours is read from the records' ``decision_ms`` of runs with ``num_envs=1`` on mpe-50
    (one team, the paper's protocol) when there are any; batched evaluations amortise the
    decision over 100 worlds and are not comparable, so they are not used."""
    columns = ("h-orca", "h-rrtstar", "h-voronoi", "mappo", "darl1n", "htamp", "mage-x", "masp")
    ours = []
    world = get_scenario("mpe-50").world
    for c in columns:
        found = [r for r in records if r["method"] == c and r["scenario"] == "mpe-50" and r.get("num_envs") == 1
                 and r.get("world", world) == world]
        ours.append(cell(found[0]["decision_ms"], latex) if found else "—")
    paper = [cell(PAPER["per-step-time"][c], latex) for c in columns]
    head = ["", *(_LABEL[c] for c in columns)]
    return Table("per-step-time", "Per-step time (ms), N = 50", get_scenario("mpe-50").world, head,
                 [["ours", *ours], ["paper", *paper]])


_PLANNERS = ("h-orca", "h-rrtstar", "h-voronoi")
_FIXED, _VARYING = ("mpe-5", "mpe-20", "mpe-50"), ("mpe-20to10", "mpe-50to20")


#: Where the training seeds of MASP with eq. 1 as written are kept (``results/training/faithful/``).
FAITHFUL = "faithful/"


def table_faithful(records, latex=False) -> Table:
    """MASP as shipped beside MASP with the Goal Matcher's reward exactly as eq. 1 writes it.

    The shipped weights end with stages whose R_GM reference is Hungarian on *squared*
    distances (:attr:`masp_lite.config.RewardConfig.gm_reference`); the faithful recipe
    trains mpe-20 from scratch with the reference on distances throughout and runs the presets
    of more agents zero-shot (its weights: ``results/training/faithful/mpe-20-seedK.pt``), where
    the shipped chain goes on to train its Goal Matcher at N = 50.
    Columns: shipped, faithful, and h-bottleneck (the min–max assignment) for scale; the
    paper row holds the paper's MASP under both MASP columns."""
    columns = [("MASP (shipped)", "masp", ""), ("MASP (eq. 1 as written)", "masp", FAITHFUL),
               ("h-bottleneck", "h-bottleneck", "")]

    def paper(sc, i):
        return None if i == 2 else PAPER["mpe" if sc in _FIXED else "mpe-varying"].get((sc, "masp"))
    return _metric_table("faithful", "MASP: shipped weights and eq. 1 as written", _FIXED + _VARYING, columns,
                         records, latex, paper)


#: Where the training seeds of ``masp-minmax`` are kept (``results/training/masp-minmax/``).
MINMAX = "masp-minmax/"


def table_beyond(records, latex=False) -> Table:
    """Beyond the paper: ``masp-minmax`` (MASP's Goal Matcher taught h-bottleneck's min-max assignment by
    imitation, :mod:`masp_lite.algos.imitation`; its kept training seeds) beside MASP as shipped and the
    assignment it imitates, on fixed and shrinking teams. The paper reports none of them: no paper rows."""
    columns = [("MASP", "masp", ""), ("masp-minmax", "masp-minmax", MINMAX), ("h-bottleneck", "h-bottleneck", "")]
    return _metric_table("beyond", "Beyond the paper: a Goal Matcher taught the min-max assignment", _FIXED + _VARYING,
                         columns, records, latex, paper=False)


#: The ablation tables (N = 20): table -> its columns ``(label, method, kept folder)``. Every variant
#: is trained with the faithful recipe and one setting changed, so MASP's column is that recipe's.
ABLATION_TABLES = {
    "ab": [("MASP w. RG", "masp-rg", "masp-rg/"), ("GM w.o. Graph", "gm-mlp", "gm-mlp/"),
           ("CAE w.o. Graph", "cae-mlp", "cae-mlp/"), ("MASP", "masp", FAITHFUL)],
    "groupsize": [("2", "masp", "group-size-2/"), ("3", "masp", FAITHFUL), ("5", "masp", "group-size-5/")],
    "globalsteps": [("1", "masp", "global-step-1/"), ("3", "masp", FAITHFUL), ("10", "masp", "global-step-10/")],
}
_ABLATION_TITLES = {"ab": "Ablations, N = 20", "groupsize": "Group size N_g, N = 20",
                    "globalsteps": "Global steps, N = 20"}


def table_ablation(name: str, records, latex=False) -> Table:
    """One of the ablation tables ("ab", "groupsize", "globalsteps"): the variants' kept
    training seeds (``results/training/FOLDER/mpe-20-seedK.pt``) on mpe-20, beside the paper's,
    each column pooling the training seeds that every column with records has."""
    columns = ABLATION_TABLES[name]

    def paper(sc, i):
        key = columns[i][1] if name == "ab" else int(columns[i][0])
        return PAPER[name].get((sc, key))
    return _metric_table(name, _ABLATION_TITLES[name], ("mpe-20",), columns, records, latex, paper, matched=True)


def _fewer_text(cut: float) -> str:
    """"12.3 % fewer", or "1.4 % more" when the cut is negative (never "-1.4 % fewer")."""
    return f"{cut:.1f} % fewer" if cut >= 0 else f"{-cut:.1f} % more"


def _steps(rec):
    return None if rec is None else rec["steps"]["mean"]


def _cut(base, masp):
    """How much fewer Steps ``masp`` needs than ``base``, in percent (None when either is missing)."""
    return None if base is None or masp is None else 100.0 * (base - masp) / base


def table_ablation_claims(records, latex=False) -> Table:
    """The paper's ablation claims at N = 20, each checked on the variants' kept seeds.

    "% fewer" is the paper's measure: how many fewer Steps MASP (or the setting it compares
    with) needs than the variant, relative to the variant — (35.91 − 24.41) / 35.91 = 32.02 %
    for "MASP w. RG". "fails" is SR below 0.5; "within 5 %" holds when the variant's Steps lie
    within 5 % of the base setting's, and shows the signed difference relative to the base."""
    def get(table, i):  # the training seeds the table's columns share, as in its table
        _, method, kept = ABLATION_TABLES[table][i]
        return pick(records, method, "mpe-20", kept, _common_seeds(records, "mpe-20", ABLATION_TABLES[table]))

    def paper(table, i):
        _, method, _ = ABLATION_TABLES[table][i]
        key = method if table == "ab" else int(ABLATION_TABLES[table][i][0])
        return {k: v[0] for k, v in PAPER[table][("mpe-20", key)].items()}

    def steps_claim(claim, table, worse, base, rule):
        def say(w, b):  # "more": the paper's "% fewer"; "near": the signed difference from the base
            return f"{w:.2f} vs {b:.2f} " + (f"({_fewer_text(_cut(w, b))})" if rule is more else
                                              f"({100.0 * (w - b) / b:+.1f} %)")
        ours_w, ours_b = _steps(get(table, worse)), _steps(get(table, base))
        theirs = say(paper(table, worse)["steps"], paper(table, base)["steps"])
        ours = "—" if ours_w is None or ours_b is None else say(ours_w, ours_b)
        rows.append([claim, theirs, ours, "—" if ours == "—" else ("yes" if rule(ours_w, ours_b) else "no")])

    rows = []
    more = lambda w, b: w > b  # noqa: E731 - the variant needs more Steps than its comparison
    near = lambda w, b: abs(w - b) <= 0.05 * b  # noqa: E731
    steps_claim("MASP w. RG needs more Steps than MASP", "ab", 0, 3, more)
    gm = get("ab", 1)
    rows.append(["GM w.o. Graph fails (SR < 0.5)", f"SR {paper('ab', 1)['sr']:.2f}",
                 "—" if gm is None else f"SR {gm['sr']['mean']:.3f}",
                 "—" if gm is None else ("yes" if gm["sr"]["mean"] < 0.5 else "no")])
    steps_claim("CAE w.o. Graph needs more Steps than MASP", "ab", 2, 3, more)
    steps_claim("N_g = 2 needs more Steps than N_g = 3", "groupsize", 0, 1, more)
    steps_claim("N_g = 5 within 5 % of N_g = 3", "groupsize", 2, 1, near)
    steps_claim("global step 10 needs more Steps than 3", "globalsteps", 2, 1, more)
    steps_claim("global step 1 within 5 % of 3", "globalsteps", 0, 1, near)
    return Table("ablation-claims", "The paper's ablation claims, checked (N = 20)", get_scenario("mpe-20").world,
                 ["Claim", "paper", "ours", "holds"], rows)


def _lowest_cr_row(records, sc: str, paper_table: dict, digits: int) -> list:
    """The claim row "MASP the lowest CR" on ``sc``: MASP against the (H) planner with the lowest CR,
    in the paper (``paper_table``) and in ``records`` (ours shown to ``digits`` decimals)."""
    paper_cr = {m: paper_table[(sc, m)]["cr"][0] for m in ("masp", *_PLANNERS)}
    paper_low = min(_PLANNERS, key=paper_cr.get)
    paper = f"{paper_cr['masp']:.2f} vs {_LABEL[paper_low]} {paper_cr[paper_low]:.2f}"
    cr = {m: pick(records, m, sc) for m in ("masp", *_PLANNERS)}
    if any(r is None for r in cr.values()):
        return ["MASP the lowest CR", sc, paper, "—", None]
    mean = {m: r["cr"]["mean"] for m, r in cr.items()}
    low = min(_PLANNERS, key=mean.get)
    return ["MASP the lowest CR", sc, paper, f"{mean['masp']:.{digits}f} vs {_LABEL[low]} {mean[low]:.{digits}f}",
            mean["masp"] < mean[low]]


def _rl_claims(records, add, paper_steps) -> None:
    """The paper's claims about its RL baselines (section "Main Results", MPE), as rows of the claims table.

    Each baseline's record is its kept training seeds (as in table "mpe"); a Steps of None (no
    episode solved) counts as worse than any number. "fails" is SR below 0.5."""
    rl = {sc: {m: pick(records, m, sc, f"{m}/") for m in _RL} for sc in _FIXED}
    theirs = {sc: {m: PAPER["mpe"][(sc, m)] for m in _RL} for sc in _FIXED}

    def steps_text(steps):
        return "\\" if steps is None else f"{steps:.2f}"

    for sc in _FIXED:
        masp = _steps(pick(records, "masp", sc))
        ours = {m: r for m, r in rl[sc].items() if r is not None}
        best_paper = min(((paper_steps(sc, m), m) for m in _RL if paper_steps(sc, m) is not None))
        solved = {m: _steps(r) for m, r in ours.items() if _steps(r) is not None}
        best = min(solved, key=solved.get) if solved else None
        text = "—" if masp is None or len(ours) < len(_RL) else \
            f"{masp:.2f} vs " + (f"{_LABEL[best]} {solved[best]:.2f}" if best else "none solved")
        add("MASP fewer Steps than every RL baseline", sc,
            f"{paper_steps(sc, 'masp'):.2f} vs {_LABEL[best_paper[1]]} {best_paper[0]:.2f}", text,
            None if text == "—" else all(masp < v for v in solved.values()))
    sc = "mpe-50"
    ours = rl[sc]
    complete = all(r is not None for r in ours.values())
    srs = ", ".join(f"{_LABEL[m]} {r['sr']['mean']:.2f}" for m, r in ours.items() if r is not None)
    add("Only (H)MAPPO keeps SR ≥ 0.99 among the RL baselines", sc,
        ", ".join(f"{_LABEL[m]} {t['sr'][0]:.2f}" for m, t in theirs[sc].items()), srs if complete else "—",
        None if not complete else ours["h-mappo"]["sr"]["mean"] >= 0.99 and
        all(r["sr"]["mean"] < 0.99 for m, r in ours.items() if m != "h-mappo"))
    others = [m for m in _RL if m != "h-mappo"]
    add("No RL baseline but (H)MAPPO completes an episode", sc,
        ", ".join(f"{_LABEL[m]} {steps_text(t['steps'][0])}" for m, t in theirs[sc].items() if m != "h-mappo"),
        ", ".join(f"{_LABEL[m]} {steps_text(_steps(ours[m]))}" for m in others) if complete else "—",
        None if not complete else all(_steps(ours[m]) is None for m in others))
    for m in ("mappo", "darl1n", "mage-x"):
        r = ours[m]
        add(f"{_LABEL[m]} fails (SR < 0.5)", sc, f"{theirs[sc][m]['sr'][0]:.2f}",
            "—" if r is None else f"{r['sr']['mean']:.2f}", None if r is None else r["sr"]["mean"] < 0.5)
    for base, target in (("h-mappo", 8.52), ("h-orca", 21.76)):
        rec = ours.get(base) or pick(records, base, sc)
        cut = _cut(_steps(rec), _steps(pick(records, "masp", sc)))
        add(f"MASP ≥ {target} % fewer Steps than {_LABEL[base]}", sc,
            f"{_cut(paper_steps(sc, base), paper_steps(sc, 'masp')):.1f} %",
            "—" if cut is None else f"{cut:.1f} %", None if cut is None else cut >= target)


def table_claims(records, latex=False) -> Table:
    """The paper's claims about MPE, each checked on our records: what the paper says, what we measured.

    From the paper's abstract and its MPE and per-step-time sections: SR, Steps against
    every (H) planner, the Steps saved against (H)RRT* (19.12 % at N = 50, 47.87 % over the
    varying team sizes; the paper's figures are against (H)RRT*, we show ours against both
    (H)RRT* and our best (H) planner), the lowest CR, and a per-step time at least 3x below
    every planner's; rows marked "ours only" compare with h-greedy, which the paper does not
    have. "holds" is "yes", "no", or "—" when a record is missing."""
    def table_of(sc):
        return "mpe" if sc in _FIXED else "mpe-varying"

    def paper_steps(sc, m):
        return PAPER[table_of(sc)][(sc, m)]["steps"][0]

    rows = []

    def add(claim, sc, paper, ours, holds):
        rows.append([claim, sc, paper, ours, "—" if holds is None else ("yes" if holds else "no")])

    for sc in _FIXED + _VARYING:
        masp = pick(records, "masp", sc)
        sr = None if masp is None else masp["sr"]["mean"]
        add("MASP SR ≥ 0.99", sc, f"{PAPER[table_of(sc)][(sc, 'masp')]['sr'][0]:.2f}",
            "—" if sr is None else f"{sr:.3f}", None if sr is None else sr >= 0.99)
    for sc in _FIXED + _VARYING:
        masp, others = _steps(pick(records, "masp", sc)), {m: _steps(pick(records, m, sc)) for m in _PLANNERS}
        known = {m: v for m, v in others.items() if v is not None}
        best = min(known, key=known.get) if known else None
        ours = "—" if masp is None or best is None else f"{masp:.2f} vs {_LABEL[best]} {known[best]:.2f}"
        paper_best = min((paper_steps(sc, m), m) for m in _PLANNERS if paper_steps(sc, m) is not None)
        add("MASP fewer Steps than every (H) planner", sc,
            f"{paper_steps(sc, 'masp'):.2f} vs {_LABEL[paper_best[1]]} {paper_best[0]:.2f}", ours,
            None if masp is None or len(known) < len(_PLANNERS) else masp < known[best])
        hg = _steps(pick(records, "h-greedy", sc))
        add("MASP fewer Steps than h-greedy (ours only)", sc, "",
            "—" if masp is None or hg is None else f"{masp:.2f} vs {hg:.2f}",
            None if masp is None or hg is None else masp < hg)
    _rl_claims(records, add, paper_steps)
    headline = round(_cut(paper_steps("mpe-50", "h-rrtstar"), paper_steps("mpe-50", "masp")), 2)  # 19.12 %
    for sc, target in [("mpe-50", headline), *((v, 47.87) for v in _VARYING)]:
        masp = _steps(pick(records, "masp", sc))
        rrt = _cut(_steps(pick(records, "h-rrtstar", sc)), masp)
        known = [v for v in (_steps(pick(records, m, sc)) for m in _PLANNERS) if v is not None]
        best = _cut(min(known), masp) if len(known) == len(_PLANNERS) else None
        ours = "—" if rrt is None else f"{rrt:.1f} % vs (H)RRT*" + ("" if best is None else f", {best:.1f} % vs best")
        paper = _cut(paper_steps(sc, "h-rrtstar"), paper_steps(sc, "masp"))
        add(f"MASP ≥ {target} % fewer Steps than (H)RRT* (and the best (H))", sc,
            f"{paper:.1f} % vs (H)RRT*", ours, None if best is None else min(rrt, best) >= target)
    for sc in _FIXED + _VARYING:
        add(*_lowest_cr_row(records, sc, PAPER[table_of(sc)], 3))
        masp, hg = pick(records, "masp", sc), pick(records, "h-greedy", sc)
        if masp is not None and hg is not None:
            add("MASP CR below h-greedy's (ours only)", sc, "", f"{masp['cr']['mean']:.3f} vs "
                f"{hg['cr']['mean']:.3f}", masp["cr"]["mean"] < hg["cr"]["mean"])
    times = {}
    for m in ("masp", *_PLANNERS):
        found = [r for r in records if r["method"] == m and r["scenario"] == "mpe-50" and r.get("num_envs") == 1
                 and r.get("world", get_scenario("mpe-50").world) == get_scenario("mpe-50").world]
        times[m] = found[0]["decision_ms"]["mean"] if found else None
    known = {m: v for m, v in times.items() if v is not None and m != "masp"}
    if times["masp"] is None or len(known) < len(_PLANNERS):
        add("MASP per-step time ≥ 3x below every planner's", "mpe-50", "≥ 2.8x", "—", None)
    else:
        fastest = min(known, key=known.get)
        ratio = known[fastest] / times["masp"]
        add("MASP per-step time ≥ 3x below every planner's", "mpe-50", "≥ 2.8x (ORCA 39 ms, MASP 14 ms)",
            f"{ratio:.2f}x ({_LABEL[fastest]} {known[fastest]:.2f} ms, MASP {times['masp']:.2f} ms)", ratio >= 3)
        rrt = known["h-rrtstar"] / times["masp"]
        p_rrt, p_masp = PAPER["per-step-time"]["h-rrtstar"][0], PAPER["per-step-time"]["masp"][0]
        add("MASP per-step time 32x below (H)RRT*'s", "mpe-50", f"{p_rrt / p_masp:.1f}x (RRT* {p_rrt} ms, MASP "
            f"{p_masp} ms)",
            f"{rrt:.2f}x ((H)RRT* {known['h-rrtstar']:.2f} ms)", rrt >= 32)
    return Table("claims", "The paper's MPE claims, checked", get_scenario("mpe-20").world,
                 ["Claim", "Scenario", "paper", "ours", "holds"], rows)


_DRONE_MASP = (("MASP", "masp", ""), _VELOCITY)
"""The learned drone methods whose claims :func:`table_drone_claims` checks: (label, method, kept folder)."""


def table_drone_claims(records, latex=False) -> Table:
    """The paper's claims about OmniDrones, each checked on our drone records.

    From its OmniDrones sections: MASP's SR (1.00 at N = 5, 96 % in the text at N = 20; the
    bars this course sets are ≥ 0.99 and ≥ 0.95), fewer Steps than every (H) planner, the
    planners needing "at least 27.92 % more Steps" at N = 20 — the share the paper's numbers
    give it, (best planner − MASP) / best planner, the same as the MPE cuts — the lowest CR, and
    at 20 => 10 "the planning-based baselines fail to reach a 100 % Success Rate" and MASP's 94 %;
    the planners' SR over 90 % and (H)Voronoi the best of them at N = 5, and what it says of its RL
    baselines (:func:`_drone_rl_claims`). MASP's claims are checked for
    the paper's executor (motor commands, ``masp``) and for the variant whose executor asks the geometric
    controller for a velocity (``masp-velocity``), each against the paper's MASP. "holds" is "yes",
    "no", or "—" when a record is missing."""
    rows = []

    def add(claim, sc, paper, ours, holds):
        rows.append([claim, sc, paper, ours, "—" if holds is None else ("yes" if holds else "no")])

    def paper_of(sc, m, key):
        table = "omnidrones-varying" if sc == "drone-20to10" else "omnidrones"
        return PAPER[table][(sc, m)][key][0]

    for name, method, kept in _DRONE_MASP:
        for sc, bar in (("drone-5", 0.99), ("drone-20", 0.95)):
            masp = pick(records, method, sc, kept)
            sr = None if masp is None else masp["sr"]["mean"]
            add(f"{name} SR ≥ {bar:.2f}", sc, f"{paper_of(sc, 'masp', 'sr'):.2f}",
                "—" if sr is None else f"{sr:.3f}", None if sr is None else sr >= bar)
    for name, method, kept in _DRONE_MASP:
        for sc in ("drone-5", "drone-20", "drone-20to10"):
            masp = _steps(pick(records, method, sc, kept))
            known = {m: v for m in _PLANNERS if (v := _steps(pick(records, m, sc))) is not None}
            best = min(known, key=known.get) if known else None
            paper = {m: paper_of(sc, m, "steps") for m in _PLANNERS if paper_of(sc, m, "steps") is not None}
            paper_best = min(paper, key=paper.get)
            add(f"{name} fewer Steps than every (H) planner", sc,
                f"{paper_of(sc, 'masp', 'steps'):.2f} vs {_LABEL[paper_best]} {paper[paper_best]:.2f}",
                "—" if masp is None or best is None else f"{masp:.2f} vs {_LABEL[best]} {known[best]:.2f}",
                None if masp is None or len(known) < len(_PLANNERS) else masp < known[best])
            if sc == "drone-20":
                cut = None if masp is None or len(known) < len(_PLANNERS) else _cut(known[best], masp)
                add(f"{name} ≥ 27.92 % fewer Steps than the best (H) planner", sc,
                    f"{_cut(paper[paper_best], paper_of(sc, 'masp', 'steps')):.1f} %",
                    "—" if cut is None else f"{cut:.1f} %", None if cut is None else cut >= 27.92)
    for sc in ("drone-5", "drone-20"):
        add(*_lowest_cr_row(records, sc, PAPER["omnidrones"], 4))
    for sc in ("drone-5", "drone-20"):  # "most planning-based baselines achieve over 90 % Success Rate"
        srs = {m: r["sr"]["mean"] for m in _PLANNERS if (r := pick(records, m, sc)) is not None}
        low = min(srs, key=srs.get) if srs else None
        paper_low = min(_PLANNERS, key=lambda m: paper_of(sc, m, "sr"))
        add("Every (H) planner SR > 0.90", sc, f"lowest {_LABEL[paper_low]} {paper_of(sc, paper_low, 'sr'):.2f}",
            "—" if len(srs) < len(_PLANNERS) else f"lowest {_LABEL[low]} {srs[low]:.3f}",
            None if len(srs) < len(_PLANNERS) else srs[low] > 0.90)
    sc = "drone-5"  # "(H)Voronoi is the best planning-based competitor at N = 5"
    known = {m: v for m in _PLANNERS if (v := _steps(pick(records, m, sc))) is not None}
    best = min(known, key=known.get) if known else None
    add("(H)Voronoi the best (H) planner (Steps)", sc, f"(H)Voronoi {paper_of(sc, 'h-voronoi', 'steps'):.2f}",
        "—" if len(known) < len(_PLANNERS) else f"{_LABEL[best]} {known[best]:.2f}",
        None if len(known) < len(_PLANNERS) else best == "h-voronoi")
    _drone_rl_claims(records, add, paper_of)
    sc = "drone-20to10"
    for name, method, kept in _DRONE_MASP:
        masp = pick(records, method, sc, kept)
        add(f"{name} SR ≥ 0.94 zero-shot", sc, f"{paper_of(sc, 'masp', 'sr'):.2f}",
            "—" if masp is None else f"{masp['sr']['mean']:.3f}",
            None if masp is None else masp["sr"]["mean"] >= 0.94)
    srs = {m: r["sr"]["mean"] for m in _PLANNERS if (r := pick(records, m, sc)) is not None}
    paper_top = max(_PLANNERS, key=lambda m: paper_of(sc, m, "sr"))
    top = max(srs, key=srs.get) if srs else None
    add("No (H) planner reaches SR 1.00", sc, f"{_LABEL[paper_top]} {paper_of(sc, paper_top, 'sr'):.2f}",
        "—" if len(srs) < len(_PLANNERS) else f"{_LABEL[top]} {srs[top]:.3f}",
        None if len(srs) < len(_PLANNERS) else srs[top] < 1.0)
    return Table("drone-claims", "The paper's OmniDrones claims, checked", get_scenario("drone-20").world,
                 ["Claim", "Scenario", "paper", "ours", "holds"], rows)


def _drone_rl_claims(records, add, paper_of) -> None:
    """The paper's claims about its RL baselines on OmniDrones, as rows of the drone claims table.

    Each baseline's record is its kept training seeds (as in table "omnidrones"). The paper: "most RL
    baselines, except MAGE-X and (H)MAPPO, achieve only around 50 % Success Rate at N = 5" (read
    here as: those two reach SR ≥ 0.9 and the other three do not), "MAGE-X drops to a 15 % Success
    Rate at N = 20" (read as SR < 0.5), MASP "superior to all competitors" in Steps (the cells say
    (H)MAPPO is the only one that needs a number) and in CR."""
    rl = {sc: {m: pick(records, m, sc, f"{m}/") for m in _RL} for sc in ("drone-5", "drone-20")}
    sc = "drone-5"
    ours, two = rl[sc], ("mage-x", "h-mappo")
    complete = all(r is not None for r in ours.values())
    add("Only MAGE-X and (H)MAPPO of the RL baselines reach SR ≥ 0.9", sc,
        ", ".join(f"{_LABEL[m]} {paper_of(sc, m, 'sr'):.2f}" for m in _RL),
        ", ".join(f"{_LABEL[m]} {r['sr']['mean']:.2f}" for m, r in ours.items()) if complete else "—",
        None if not complete else all((ours[m]["sr"]["mean"] >= 0.9) == (m in two) for m in _RL))
    r = rl["drone-20"]["mage-x"]
    add("MAGE-X drops at N = 20 (SR < 0.5)", "drone-20", f"{paper_of('drone-20', 'mage-x', 'sr'):.2f}",
        "—" if r is None else f"{r['sr']['mean']:.2f}", None if r is None else r["sr"]["mean"] < 0.5)
    for name, method, kept in _DRONE_MASP:
        for sc in ("drone-5", "drone-20"):
            masp, hm = _steps(pick(records, method, sc, kept)), _steps(rl[sc]["h-mappo"])
            add(f"(H)MAPPO needs more Steps than {name}", sc,
                f"{paper_of(sc, 'h-mappo', 'steps'):.2f} vs {paper_of(sc, 'masp', 'steps'):.2f}",
                "—" if masp is None or hm is None else f"{hm:.2f} vs {masp:.2f}",
                None if masp is None or hm is None else hm > masp)
    for sc in ("drone-5", "drone-20"):
        masp, ours = pick(records, "masp", sc), rl[sc]
        paper_cr = {m: paper_of(sc, m, "cr") for m in _RL}
        paper_low = min(_RL, key=paper_cr.get)
        known = {m: r["cr"]["mean"] for m, r in ours.items() if r is not None}
        low = min(known, key=known.get) if known else None
        done = masp is not None and len(known) == len(_RL)
        add("MASP CR below every RL baseline's", sc,
            f"{paper_of(sc, 'masp', 'cr'):.2f} vs {_LABEL[paper_low]} {paper_cr[paper_low]:.2f}",
            f"{masp['cr']['mean']:.4f} vs {_LABEL[low]} {known[low]:.4f}" if done else "—",
            masp["cr"]["mean"] < known[low] if done else None)


TABLES = {"mpe": table_mpe, "mpe-varying": table_mpe_varying, "omnidrones": table_omnidrones,
          "omnidrones-varying": table_omnidrones_varying, "per-step-time": table_time, "claims": table_claims,
          "drone-claims": table_drone_claims, "faithful": table_faithful, "beyond": table_beyond,
          **{name: (lambda records, latex=False, name=name: table_ablation(name, records, latex))
             for name in ABLATION_TABLES},
          "ablation-claims": table_ablation_claims}


def _drone_weights(method: str, scenario: str) -> bool:
    """Whether ``masp`` has shipped weights for a drone scenario here."""
    return base_scenario(scenario) in read_manifest()


def evaluation_jobs(table: str) -> list[tuple[str, str, dict]]:
    """``(method, scenario, evaluate keyword arguments)`` of every fresh record ``table`` needs: every
    registered method of its columns with the shipped weights, or with every kept training seed where
    a column reads kept weights (the RL baselines, the ablations, the faithful recipe)."""
    if table not in TABLES:
        raise ValueError(f"unknown table {table!r}; expected one of {list(TABLES)}")
    sources = {"claims": ("mpe", "mpe-varying", "per-step-time"), "drone-claims": ("omnidrones", "omnidrones-varying"),
               "ablation-claims": tuple(ABLATION_TABLES)}
    if table in sources:  # every record the tables it checks read
        return [job for t in sources[table] for job in evaluation_jobs(t)]
    if table == "faithful" or table in ABLATION_TABLES:  # kept training seeds of the source checkout
        columns = [("", "masp", ""), ("", "masp", FAITHFUL), ("", "h-bottleneck", "")] if table == "faithful" \
            else ABLATION_TABLES[table]
        runs = []
        for _, method, kept in columns:
            found = sorted((RESULTS_DIR / "training" / kept).glob("mpe-20-seed*.pt")) if kept else [None]
            runs += [(method, None if k is None else f"results/training/{kept}{k.name}") for k in found]
        scenarios = _FIXED + _VARYING if table == "faithful" else ("mpe-20",)
        jobs = []
        for sc in scenarios:
            for m, checkpoint in runs:
                if checkpoint and get_scenario(sc).num_agents < 20:  # kept mpe-20 weights fly 20 agents or more
                    continue
                zero_shot = bool(checkpoint) and base_scenario(sc) != "mpe-20"
                jobs.append((m, sc, {**({"checkpoint": checkpoint} if checkpoint else {}),
                                     "method_options": {"any_scenario": True} if zero_shot else {}}))
        return jobs
    if table == "beyond":  # the shipped MASP, h-bottleneck and masp-minmax's kept training seeds
        kept = sorted((RESULTS_DIR / "training" / MINMAX).glob("*-seed*.pt"))
        return [job for sc in _FIXED + _VARYING
                for job in [("masp", sc, {}), ("h-bottleneck", sc, {})] +
                [("masp-minmax", sc, {"checkpoint": f"results/training/{MINMAX}{k.name}"}) for k in kept
                 if k.name.startswith(f"{base_scenario(sc)}-seed")]]
    if table == "per-step-time":
        return [(m, "mpe-50", {"num_envs": 1}) for m in ("h-orca", "h-rrtstar", "h-voronoi", "masp")]
    scenarios = {"mpe": ("mpe-5", "mpe-20", "mpe-50"), "mpe-varying": ("mpe-20to10", "mpe-50to20"),
                 "omnidrones": ("drone-5", "drone-20"), "omnidrones-varying": ("drone-20to10",)}[table]
    columns = build(table, []).head[3:]  # the table's own columns, by label
    label_to = {label: (m, kept) for label, m, kept in
                _columns(_MPE_COLUMNS + _OURS_ONLY) + [("MASP (budget)", "masp", "masp-budget/"), _VELOCITY]}
    runs = []
    for sc in scenarios:
        for m, kept in (label_to[c] for c in columns):
            if m not in METHODS:
                continue
            if not kept:  # the shipped method
                if sc.startswith("drone") and _learned(m) and not _drone_weights(m, sc):
                    continue  # no drone weights in this checkout
                runs.append((m, sc, {"method_options": {}}))
                continue
            for k in sorted((RESULTS_DIR / "training" / kept).glob(f"{base_scenario(sc)}-seed*.pt")):
                runs.append((m, sc, {"checkpoint": f"results/training/{kept}{k.name}"}))
    return runs


def evaluate_records(tables, episodes: int = 100, seeds=(0, 1, 2), progress: bool = False) -> list[dict]:
    """Fresh records for the cells of ``tables`` (a name or several, see :func:`evaluation_jobs`),
    each distinct evaluation run once even when several tables read it."""
    jobs = {}
    for t in [tables] if isinstance(tables, str) else tables:
        for m, sc, kw in evaluation_jobs(t):
            jobs.setdefault(json.dumps([m, sc, kw], sort_keys=True), (m, sc, kw))
    return [evaluate(m, sc, episodes=episodes, seeds=list(seeds), progress=progress, **kw)
            for m, sc, kw in jobs.values()]


def build(name: str, records, latex: bool = False) -> Table:
    if name not in TABLES:
        raise ValueError(f"unknown table {name!r}; expected one of {list(TABLES)}")
    return TABLES[name](records, latex)


def render(table: Table, fmt: str = "markdown") -> str:
    """The table as ``text``, ``markdown`` or ``latex``, with its title and world on top."""
    caption = f"{table.title} — world: {world_name(table.world)}"
    if fmt == "text" and len(caption) > WIDTH:
        caption = f"{table.title}\nworld: {world_name(table.world)}"
    body = render_rows(table.head, table.rows, fmt)
    if fmt == "latex":
        return "\n".join([body, f"% {caption}", *(f"% {n}" for n in table.notes)])
    if fmt == "text":
        return "\n".join([caption, *_text_chunks(table), *_compact_notes(table.notes)])
    return "\n".join([f"**{caption}**", "", body, *([""] + [f"- {n}" for n in table.notes] if table.notes else [])])


WIDTH = 100
"""Columns a ``text`` table fits in: wider tables are split into column groups, each with the key columns."""
CELL = 48
"""Longest ``text`` cell on one line; a longer one (a claim, its figures) is wrapped."""
LEGEND = ("Legend: per metric, our number above the paper's; ↓ lower is better, ↑ higher is better; "
          "\\ no episode reached SR 1 (Steps undefined, the paper's mark); — no record here; "
          "blank: the paper gives no number")
"""The one line under ``text`` output that says what the marks mean (:func:`text_legend`)."""


def _text_chunks(table: Table) -> list[str]:
    """The table's ``text`` rendering split into column groups of at most :data:`WIDTH` columns."""
    keys = 3 if len(table.head) > 3 and table.head[:2] == ["Agents", "Metric"] else 1
    rows = []
    for row in table.rows:  # a long cell (a claim, its figures) goes on several lines
        parts = [textwrap.wrap(c, CELL) or [""] if len(c) > CELL else [c] for c in row]
        rows += [[p[k] if k < len(p) else "" for p in parts] for k in range(max(map(len, parts)))]
    table = dataclasses.replace(table, rows=rows)
    cols = list(zip(table.head, *table.rows)) if table.rows else [[h] for h in table.head]
    width = [max(len(c) for c in col) + 2 for col in cols]
    groups, current, used = [], [], sum(width[:keys])
    for j in range(keys, len(cols)):
        if current and used + width[j] > WIDTH:
            groups.append(current)
            current, used = [], sum(width[:keys])
        current.append(j)
        used += width[j]
    groups.append(current)
    out = []
    for g in groups:
        idx = list(range(keys)) + g
        out.append(render_rows([table.head[i] for i in idx],
                               [[row[i] if i < len(row) else "" for i in idx] for row in table.rows], "text"))
    return out


def _compact_notes(notes) -> list[str]:
    """Notes of the form "WHERE: WHAT" said once per WHAT ("WHAT: WHERE; WHERE"), wrapped at :data:`WIDTH`."""
    grouped = {}
    for n in notes:
        where, sep, what = n.rpartition(": ")
        grouped.setdefault(what if sep else n, []).append(where if sep else "")
    lines = []
    for what, wheres in grouped.items():
        by_label = {}  # "mpe-5, MASP" and "mpe-20, MASP" -> MASP (mpe-5, mpe-20)
        for w in filter(None, wheres):
            sc, sep, label = w.partition(", ")
            by_label.setdefault(label if sep else w, []).append(sc if sep else "")
        by_places = {}
        for label, places in by_label.items():
            by_places.setdefault(tuple(p for p in places if p), []).append(label)
        said = "; ".join(", ".join(labels) + (f" ({', '.join(places)})" if places else "")
                         for places, labels in by_places.items())
        lines += textwrap.wrap(f"{what}: {said}" if said else what, WIDTH, subsequent_indent="  ")
    return lines


def text_legend() -> list[str]:
    """:data:`LEGEND` wrapped at :data:`WIDTH` columns."""
    return textwrap.wrap(LEGEND, WIDTH, subsequent_indent="  ")


BLOCK = re.compile(r"(<!-- reproduce ([\w-]+) -->\n)(.*?)(\n<!-- /reproduce -->)", flags=re.S)
"""A table kept in a Markdown file (README.md, results/*/README.md): ``<!-- reproduce NAME -->``, the
table, ``<!-- /reproduce -->``."""


def fill_blocks(text: str, records) -> str:
    """``text`` with every ``<!-- reproduce NAME -->`` block replaced by table NAME in markdown, from ``records``."""
    return BLOCK.sub(lambda m: m.group(1) + render(build(m.group(2), records), "markdown") + m.group(4), text)
