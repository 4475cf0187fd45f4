"""The reference table of sensorless force estimation: force sources × error sources.

Rows (:data:`ROWS`) are the force sources a robot's control block can hold, columns
(:data:`COLUMNS`) the error sources the run is put under; a cell is one row under one column,
run for ``draws`` paired draws. Every draw ``i`` of a column draws that column's random values
from ``numpy.random.default_rng([seed, column index, i])``, the same for every row (the rows of
a column are compared on the same draws), and sets every noise seed to ``i``.

The short segment
-----------------
A cell runs the paper's task compressed (:data:`SEGMENT`): free motion 0–2 s, the pre-grasp
approach 2–3 s, the grasp at 3 s, the lift 3–5 s, then the circle from 5 s with the paper's
period (40 s) and force profile (29), stopped at ``t_end`` (:data:`T_SHORT` = 8 s: the first
3 s of the circle, where the full run's squeeze error is largest). The per-draw numbers are the
circle phase's RMS, worst robot, of the squeeze error ``λ − λ_d`` (the estimator in the loop)
and of the estimate's error ``λ̂ − λ`` (the estimate the loop ran on, against the simulated
truth). Whether the short segment ranks the estimators as the full run does is checked by
:mod:`bench.reference_table` (``--agreement``) on cells the shipped studies cover.

Statistics
----------
Per cell and number: the median and the 90th percentile over the draws, each with a 95 %
bootstrap interval (:func:`bootstrap_interval`: 2 000 resamples of the draws, a fixed seed:
the same numbers on every machine). The dominant error source of a row is the column, other
than the exact model, with the largest median squeeze error.

The box held by friction
------------------------
On a base in ``contact`` mode (the box held at two hydroelastic pads, ``scenarios/contact.yaml``
or a lab pair) the default columns are :data:`FRICTION_COLUMNS` (the error sources that matter
there: model error, identification, friction, saturation), and a cell also counts what the
run's object metrics (:mod:`drake_coop.results.object_metrics`) report over the whole case,
grasp and lift included: ``slips`` (the pads' slides of
:data:`~drake_coop.results.object_metrics.SLIP_DISTANCE` on the box's faces, both robots,
summed over the draws), ``slipped`` and ``dropped`` (draws with at least one slip, one drop:
the box off its path or a pad letting go) and ``slide`` (the worst pad's largest slide since
the grasp, m: median and 90th percentile). A case whose grasp guard stopped it is a diverged
draw, its drop counted when its metrics show one.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.schema import Scenario
from drake_coop.studies.expand import Case, case_hash
from drake_coop.studies.reference_variants import variant_hash, variant_matters

__all__ = ["ALL_COLUMNS", "ALL_ROWS", "COLUMNS", "FRICTION_COLUMNS", "IDENTIFIED", "OPTIONAL_ROWS",
           "ROWS", "SEGMENT", "T_SHORT", "Column", "Row", "bootstrap_interval", "cell_statistics",
           "check_optional_rows", "compress", "default_columns", "expand_table", "identified_name",
           "markdown_table", "per_draw"]

#: The compressed task: the paper's phases shortened before the circle (s).
SEGMENT = {"t_pregrasp": 2.0, "t_grasp": 3.0, "t_circle_start": 5.0, "t_circle_end": 45.0,
           "t_release": 55.0, "t_end": 60.0}
#: Where a cell stops by default (s): 3 s of the circle.
T_SHORT = 8.0
#: Bootstrap resamples and their generator's seed.
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20261129


@dataclass(frozen=True)
class Row:
    """A force source of the table.

    Attributes
    ----------
    name : str
        Its key (file names, ``--rows``).
    label : str
        Its name in the table.
    apply : callable
        ``apply(scenario, draw)``: sets the source on every robot, in place.
    variant : str or None
        A force source no scenario field selects, built by the worker
        (:mod:`~drake_coop.studies.reference_variants`); None: the scenario's own.
    """

    name: str
    label: str
    apply: Callable[[Scenario, int], None]
    variant: str | None = None


@dataclass(frozen=True)
class Column:
    """An error source of the table.

    Attributes
    ----------
    name : str
        Its key.
    label : str
        Its name in the table.
    apply : callable
        ``apply(scenario, rng, draw)``: puts the run under the error, in place; ``rng`` is the
        column's generator for this draw (the same for every row).
    draws_like : str or None
        Another column whose generator this one's draws use (an identified column draws its
        prior as the ±30 % column does); None: its own.
    """

    name: str
    label: str
    apply: Callable[[Scenario, np.random.Generator, int], None]
    draws_like: str | None = None


#: The identified columns: (estimator, excitation length in s), identified from the ±30 %
#: column's draw (its controller models are the identification's prior), the excitation read
#: through the encoders column's draw of the same index (31 µrad counts, noise 0.05–0.2 mrad:
#: an identification on a real arm reads its real encoders; noise-free data would hand the
#: closed-loop estimators the exact model). The run itself reads exact encoders: the column's
#: only error is the identified model.
IDENTIFIED = tuple((m, b) for b in (2.0, 5.0, 10.0) for m in ("map_sdp", "idim_iv", "didim"))


def identified_name(estimator: str, duration: float) -> str:
    """The column name of an identified column, e.g. ``id_didim_5s``.

    Parameters
    ----------
    estimator : str
        ``map_sdp``, ``idim_iv`` or ``didim``.
    duration : float
        The excitation's length, s.

    Returns
    -------
    str
        The name.
    """
    return f"id_{estimator}_{duration:g}s"


def _identified(models: dict, name: str) -> Callable:
    def apply(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
        _model_30(scenario, rng, draw)           # the prior: the ±30 % column's draw
        for robot in scenario.robots:
            robot.controller_model = models[(name, draw)][robot.name]
            e = robot.model_error
            e.mass_scale = e.inertia_scale = e.damping_scale = 1.0
    return apply


def _source(name: str, noise: float | None = None) -> Callable[[Scenario, int], None]:
    """The row's force source; the sensor's noise seed is the draw's for the rows that read
    the sensor only (for the others the seed changes nothing the table reads: a column
    without random values then runs one case per row, shared by its draws)."""
    def apply(scenario: Scenario, draw: int) -> None:
        for robot in scenario.robots:
            robot.force_source = name
            if noise is not None:
                robot.force_sensor.noise_std = noise
            if name == "sensor":
                robot.force_sensor.seed = draw
    return apply


ROWS: tuple[Row, ...] = (
    Row("observer", "force observer (22)", _source("observer")),
    Row("momentum", "momentum observer", _source("momentum")),
    Row("sensor_0p3", "F/T sensor, σ = 0.3 N", _source("sensor", 0.3)),
    Row("sensor_3", "F/T sensor, σ = 3 N", _source("sensor", 3.0)),
    Row("none", "none (λ̂ = λ_d)", _source("none")),
    Row("applied_torque", "applied-torque residual", _source("momentum"), "applied_torque"),
    Row("online", "online identification + momentum", _source("momentum"), "online"),
)
#: Rows run only when ``--rows`` names them (not in the default table): an option's variant
#: of a default row, e.g. the online identification with the friction's prior floor.
OPTIONAL_ROWS: tuple[Row, ...] = (
    Row("online_prior", "online identification, Coulomb prior 0.5 N·m + momentum",
        _source("momentum"), "online_prior"),
)
#: Every row, the optional ones included.
ALL_ROWS: tuple[Row, ...] = ROWS + OPTIONAL_ROWS


def _exact(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
    """Nothing: the controller's model is the plant's, sensing ideal."""


def _model_30(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
    for robot in scenario.robots:
        e = robot.model_error
        e.mass_scale, e.inertia_scale, e.damping_scale = (float(v) for v in
                                                          rng.uniform(0.7, 1.3, 3))


#: Joint counts per robot, by the robots' model files (parsing a lab arm's takes seconds).
_JOINTS: dict = {}


def _coulomb(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
    """Coulomb friction ``U(0, 1)`` N·m on every joint of every arm (its joint count read
    from its model: a lab arm has more than the paper's three)."""
    from drake_coop.scenario.model_check import check_models

    key = tuple((r.model, r.controller_model, tuple(r.locked_joints)) for r in scenario.robots)
    if key not in _JOINTS:
        _JOINTS[key] = check_models(scenario)
    for robot, joints in zip(scenario.robots, _JOINTS[key]):
        robot.model_error.coulomb_friction = [float(v) for v in rng.uniform(0.0, 1.0, joints)]


#: Torque limits of the saturation column: each joint's limit is this fraction of the peak
#: ``|τ|`` the exact run commands over the lift (the calibration run of :func:`expand_table`),
#: times a draw's factor ``U(0.95, 1.05)``, but never below 1.02 times its peak outside the
#: lift: only the lift saturates. On a box held by friction, never below
#: :data:`NEED_MARGIN` times what the grasp check needs along the reference (the calibration's
#: ``need``): tighter limits cannot hold the box on its path and the run is refused before it
#: starts, so there the column is the tightest limits the check accepts, clipping the lift's
#: transients only where they exceed the need.
SATURATION_FRACTION = 0.9
#: The margin over the grasp check's need of the saturation column's limits on a friction
#: base.
NEED_MARGIN = 1.01


def _saturation(peaks: dict) -> Callable:
    def apply(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
        for i, robot in enumerate(scenario.robots):
            lift, other = (np.asarray(peaks[robot.name][k]) for k in ("lift", "other"))
            limit = np.maximum(SATURATION_FRACTION * lift * rng.uniform(0.95, 1.05, lift.size),
                               1.02 * other)
            if "need" in peaks[robot.name]:          # a box held by friction
                limit = np.maximum(limit, NEED_MARGIN * np.asarray(peaks[robot.name]["need"]))
            robot.actuators.torque_limits = [float(v) for v in limit]
    return apply


def _encoders(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
    for robot in scenario.robots:
        robot.encoders.counts_per_rev = 200000       # realistic.yaml's robot 1 (31 µrad)
        robot.encoders.noise_std = float(rng.uniform(0.5e-4, 2e-4))   # rad
        robot.encoders.seed = draw


def _timing(scenario: Scenario, rng: np.random.Generator, draw: int) -> None:
    """A delay ``U(0.5, 2)`` ms and the exponential lateness (mean 1.1 ms) of a stock-kernel
    Python loop (``studies/timing.yaml``)."""
    for robot in scenario.robots:
        robot.timing.computation_delay = float(rng.uniform(0.5e-3, 2e-3))
        robot.timing.jitter = "exponential"
        robot.timing.jitter_scale = 1.1e-3
        robot.timing.seed = draw


def columns(peaks: dict | None = None, models: dict | None = None) -> tuple[Column, ...]:
    """The table's error sources (the saturation column needs the calibration's peaks, the
    identified columns their models).

    Parameters
    ----------
    peaks : dict or None
        ``peaks[robot]["lift" | "other"]``: the exact run's peak ``|τ|`` per joint (N·m) over the
        lift and outside it; None leaves the saturation column out.
    models : dict or None
        ``models[(column, draw)][robot]``: the identified URDF of each identified column's
        draw; None leaves the identified columns out.

    Returns
    -------
    tuple of Column
        The columns, in the table's order.
    """
    cols = [Column("exact", "exact model", _exact),
            Column("model_30", "±30 % model", _model_30),
            Column("coulomb", "Coulomb friction 0–1 N·m", _coulomb)]
    if peaks is not None:
        cols.append(Column("saturation", "torque saturation (lift)", _saturation(peaks)))
    cols += [Column("encoders", "encoders 31 µrad, noise 0.05–0.2 mrad", _encoders),
             Column("timing", "delay 0.5–2 ms, jitter 1.1 ms", _timing),
             Column("clock", "clock skew: robot 2 at phase U(0, h), rate ±100 ppm", _exact)]
    if models is not None:
        cols += [Column(identified_name(m, b), f"identified, {m}, {b:g} s (noisy encoders)",
                        _identified(models, identified_name(m, b)), draws_like="model_30")
                 for m, b in IDENTIFIED]
    cols.append(Column("open_loop", "open loop: beside the F/T loop (σ 0.3 N)", _exact))
    return tuple(cols)


def _open_loop(scenario: Scenario, row: str, draw: int) -> str | None:
    """The open-loop column's case of ``row`` (:mod:`~drake_coop.studies.reference_open_loop`):
    every loop on the F/T sensor and the row's estimator beside it (its variant returned);
    None for the F/T rows (their exact column's case)."""
    from drake_coop.studies.reference_open_loop import BESIDE, LOOP_NOISE

    if row not in BESIDE:
        return None
    if row == "applied_torque" and not any(r.actuators.torque_limits for r in scenario.robots):
        row = "momentum"                        # the same system without limits
    _source("sensor", LOOP_NOISE)(scenario, draw)
    return f"open_loop:{row}"


#: The column names of the default table (the saturation column included, the identified
#: columns not: ``--columns`` names them, :data:`ALL_COLUMNS`).
COLUMNS = tuple(c.name for c in columns({}))
#: Every column name.
ALL_COLUMNS = tuple(c.name for c in columns({}, {}))
#: The default columns of a base in ``contact`` mode (the box held by friction): model error,
#: identification (MAP-SDP from 5 s, the cheapest estimator that holds its consistency
#: constraints), Coulomb friction and saturation.
FRICTION_COLUMNS = ("exact", "model_30", "coulomb", "saturation", identified_name("map_sdp", 5.0))


def default_columns(base: Scenario) -> tuple[str, ...]:
    """The columns a table on ``base`` runs when none are named.

    Parameters
    ----------
    base : Scenario
        The base scenario.

    Returns
    -------
    tuple of str
        :data:`FRICTION_COLUMNS` for a base in ``contact`` mode, else :data:`COLUMNS`.
    """
    return FRICTION_COLUMNS if base.plant.object_mode == "contact" else COLUMNS


def compress(scenario: Scenario) -> Scenario:
    """A copy of ``scenario`` on the short segment (:data:`SEGMENT`).

    Parameters
    ----------
    scenario : Scenario
        The base scenario.

    Returns
    -------
    Scenario
        A copy of the scenario with the task compressed to the table's segment.
    """
    out = copy.deepcopy(scenario)
    for key, value in SEGMENT.items():
        setattr(out.task, key, value)
    return out


def check_optional_rows(rows: list[str], cols: list[str]) -> None:
    """Refuse an optional row (:data:`OPTIONAL_ROWS`) with the open-loop column: its variant
    has no open-loop case (the open-loop column's estimators are the default rows').

    Parameters
    ----------
    rows, cols : list of str
        Row and column names.

    Raises
    ------
    ValueError
        An optional row and ``open_loop`` together.
    """
    optional = [r for r in rows if r in {o.name for o in OPTIONAL_ROWS}]
    if optional and "open_loop" in cols:
        raise ValueError(f"columns: open_loop has no case of the optional row {optional[0]!r}; "
                         "leave one of them out")


def expand_table(base: Scenario, rows: list[str], cols: list[str], draws: int, *,
                 seed: int = 1, t_end: float = T_SHORT, peaks: dict | None = None,
                 models: dict | None = None) -> list[Case]:
    """The table's cases, cell by cell (row outer, column, then draw), each validated.

    Parameters
    ----------
    base : Scenario
        The base scenario (compressed here).
    rows, cols : list of str
        Row and column names (of :data:`ALL_ROWS` and :data:`ALL_COLUMNS`).
    draws : int
        Draws per cell (>= 1).
    seed : int
        The draws' seed.
    t_end : float
        Every case's end (s).
    peaks : dict or None
        The saturation column's calibration (:func:`columns`); needed when ``cols`` names it.
    models : dict or None
        The identified columns' models (:func:`columns`); needed when ``cols`` names one.

    Returns
    -------
    list of Case
        ``params`` = ``{"row", "column", "draw"}``; ``values`` also ``variant``: the force
        source the worker builds (:mod:`~drake_coop.studies.reference_variants`), or None.

    Raises
    ------
    ValueError
        An unknown row or column, a count below 1, the saturation column without ``peaks``,
        the open-loop column with an optional row (it has no open-loop case).
    """
    from drake_coop.experiment.ticks import check_run_size, time_grid
    from drake_coop.studies.reference_clock import clock_variant, draw_clock
    from drake_coop.scenario.validation import validate

    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 1:
        raise ValueError(f"draws: must be an integer >= 1, got {draws!r}")
    known_rows = {r.name: r for r in ALL_ROWS}
    table_cols = {c.name: (k, c) for k, c in enumerate(columns(
        peaks if peaks is not None else {}, models if models is not None else {}))}
    for name in rows:
        if name not in known_rows:
            raise ValueError(f"rows: unknown row {name!r}; allowed: {', '.join(known_rows)}")
    for name in cols:
        if name not in table_cols:
            raise ValueError(f"columns: unknown column {name!r}; allowed: "
                             f"{', '.join(table_cols)}")
    check_optional_rows(rows, cols)
    if "saturation" in cols and peaks is None:
        raise ValueError("columns: saturation needs the calibration run's peaks")
    for col in cols:
        if col.startswith("id_") and not all((col, d) in (models or {}) for d in range(draws)):
            raise ValueError(f"columns: {col} needs its identified models")
    short = compress(base)
    cases: list[Case] = []
    cache: dict = {}
    for row in rows:
        for col in cols:
            k, column = table_cols[col]
            if column.draws_like is not None:
                k = table_cols[column.draws_like][0]
            for draw in range(draws):
                s = copy.deepcopy(short)
                column.apply(s, np.random.default_rng([seed, k, draw]), draw)
                known_rows[row].apply(s, draw)
                variant = (_open_loop(s, row, draw) if col == "open_loop"
                           else known_rows[row].variant)
                validate(s, cache=cache)
                check_run_size(s, t_end)
                params = {"row": row, "column": col, "draw": draw}
                key = case_hash(s, t_end)
                if not variant_matters(s, variant):  # the scenario's own case
                    variant = None
                if col == "clock":                   # robot 2 on its own clock
                    variant = clock_variant(draw_clock(np.random.default_rng(
                        [seed, k, draw]), time_grid(s)[0]), variant)
                if variant is not None:
                    key = variant_hash(key, variant)
                cases.append(Case(index=len(cases), params=params,
                                  values={**params, "variant": variant}, scenario=s, hash=key))
    return cases


def torque_peaks(logs: dict, meta: dict) -> dict:
    """Per robot, the peak ``|τ|`` per joint over the lift and outside it (N·m).

    Parameters
    ----------
    logs : dict
        A run's logs (``logs[robot]["t"]``, ``["tau"]``).
    meta : dict
        Its metadata (``phases``).

    Returns
    -------
    dict
        ``{robot: {"lift": [...], "other": [...]}}``.
    """
    (t0, t1), = [(p[1], p[2]) for p in meta["phases"] if p[0] == "lift"]
    out = {}
    for robot, log in logs.items():
        t, tau = np.asarray(log["t"]), np.abs(np.asarray(log["tau"]))
        lift = (t >= t0) & (t < t1)
        out[robot] = {"lift": tau[lift].max(axis=0).tolist(),
                      "other": tau[~lift].max(axis=0).tolist()}
    return out


def per_draw(record: dict) -> dict[str, float]:
    """The numbers of one finished case: the circle's RMS, worst robot, of ``λ − λ_d``
    (``squeeze``) and ``λ̂ − λ`` (``estimate``), NaN when the case did not complete.

    Parameters
    ----------
    record : dict
        The case's record (``status``, ``metrics``).

    Returns
    -------
    dict of str to float
        ``squeeze``, ``estimate`` (N), ``squeeze_lift`` (the lift's RMS of ``λ − λ_d``, worst
        robot, N) and ``diverged`` (0 or 1); for a run holding the box by friction also
        ``slips`` (both robots' counts over the run), ``drops`` (0 or 1) and ``slide`` (the
        worst pad's largest slide since the grasp, m), also when it did not complete.
    """
    out = {"squeeze": math.nan, "estimate": math.nan, "squeeze_lift": math.nan,
           "diverged": float(record["status"] != "ok")}
    out.update(_held(record.get("metrics") or {}))
    if record["status"] != "ok":
        return out
    for key, phase, error in (("squeeze", "circle", "force_error"),
                              ("estimate", "circle", "estimate_error"),
                              ("squeeze_lift", "lift", "force_error")):
        values = [m[phase][error]["rms"] for m in record["metrics"].values()
                  if phase in m and error in m[phase]]
        if values:
            out[key] = float(max(values))
    return out


def _held(metrics: dict) -> dict[str, float]:
    """Slips, drops and the largest slide of a contact run's whole-run (``all``) metrics;
    empty for a run without an object held by friction."""
    runs = [m["all"] for m in metrics.values() if "slips" in m.get("all", {})]
    if not runs:
        return {}
    slides = [a["slip"]["max"] for a in runs if "slip" in a and a["slip"].get("max") is not None]
    return {"slips": float(sum(a["slips"]["count"] for a in runs)),
            "drops": float(max(a["drops"]["count"] for a in runs) > 0),
            "slide": float(max(slides)) if slides else math.nan}


def bootstrap_interval(values: np.ndarray, q: float, *, level: float = 0.95,
                       resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED
                       ) -> tuple[float, float, float]:
    """The ``q`` quantile of ``values`` and its percentile-bootstrap interval.

    Parameters
    ----------
    values : numpy.ndarray
        The draws' values (NaN: a case that did not complete, left out).
    q : float
        The quantile, 0 … 1 (0.5 the median).
    level : float
        The interval's coverage.
    resamples : int
        Bootstrap resamples.
    seed : int
        Their generator's seed (fixed: the same interval on every machine).

    Returns
    -------
    estimate, low, high : float
        NaN when no value is finite.
    """
    x = np.asarray(values, float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    boot = np.quantile(x[rng.integers(0, x.size, (resamples, x.size))], q, axis=1)
    a = (1.0 - level) / 2.0
    return float(np.quantile(x, q)), float(np.quantile(boot, a)), float(np.quantile(boot, 1 - a))


def cell_statistics(records: list[dict]) -> dict:
    """Median and 90th percentile (each with its 95 % interval) of a cell's draws.

    Parameters
    ----------
    records : list of dict
        The cell's finished case records.

    Returns
    -------
    dict
        ``{"n", "diverged", "squeeze": {"median": [v, lo, hi], "p90": [...]},
        "estimate": {...}, "squeeze_lift": {...}}``; with the box held by friction also
        ``slide`` (as those, m), ``slips`` (summed over the draws), ``slipped`` and
        ``dropped`` (draws with a slip, with a drop).
    """
    numbers = [per_draw(r) for r in records]
    out = {"n": len(numbers), "diverged": int(sum(v["diverged"] for v in numbers))}
    held = [v for v in numbers if "slips" in v]
    keys = ("squeeze", "estimate", "squeeze_lift") + (("slide",) if held else ())
    for key in keys:
        x = np.array([v.get(key, math.nan) for v in numbers])
        out[key] = {"median": list(bootstrap_interval(x, 0.5)),
                    "p90": list(bootstrap_interval(x, 0.9))}
    if held:
        out["slips"] = int(sum(v["slips"] for v in held))
        out["slipped"] = int(sum(v["slips"] > 0 for v in held))
        out["dropped"] = int(sum(v["drops"] for v in held))
    return out


def _fmt(stat: list[float]) -> str:
    v, lo, hi = stat
    if not math.isfinite(v):
        return "—"
    return f"{v:.3f} [{lo:.3f}, {hi:.3f}]"


def markdown_table(table: dict, key: str = "squeeze") -> str:
    """The table of one number as Markdown: a cell ``median [95 %] / p90 [95 %]``, the row's
    diverged draws, and its dominant error source.

    Parameters
    ----------
    table : dict
        ``{"rows": [...], "columns": [...], "cells": {row: {column: statistics}}}`` (as
        :func:`cell_statistics` gives each cell).
    key : str
        ``squeeze`` or ``estimate``.

    Returns
    -------
    str
        The table as Markdown, one row per force source.
    """
    rows, cols = table["rows"], table["columns"]
    labels = {r.name: r.label for r in ALL_ROWS}
    col_labels = {c.name: c.label for c in columns({}, {})}
    head = ["force source", *[col_labels[c] for c in cols], "dominant error source"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in rows:
        cells, worst = [], (None, -math.inf)
        for col in cols:
            s = table["cells"].get(row, {}).get(col)
            if s is None:
                cells.append("pending")
                continue
            text = f"{_fmt(s[key]['median'])} / {_fmt(s[key]['p90'])}"
            if s["diverged"]:
                text += f" ({s['diverged']} of {s['n']} diverged)"
            if "slips" in s:
                text += f"; slips {s['slips']} ({s['slipped']} draws), drops {s['dropped']}"
            cells.append(text)
            median = s["squeeze"]["median"][0]
            if col != "exact" and (s["diverged"] or (math.isfinite(median)
                                                     and median > worst[1])):
                worst = (col, math.inf if s["diverged"] else median)
        lines.append(f"| {labels[row]} | " + " | ".join(cells)
                     + f" | {col_labels.get(worst[0], '—')} |")
    return "\n".join(lines)


def base_scenario(path: str | None = None) -> Scenario:
    """The table's base: ``path`` or the paper's scenario (ideal constraint), validated.

    Parameters
    ----------
    path : str or None
        A scenario file; None for the paper's.

    Returns
    -------
    Scenario
        The scenario.
    """
    return load_scenario(path) if path else load_scenario()


def scenario_text(case: Case) -> str:
    """A case's scenario as YAML text.

    Parameters
    ----------
    case : Case
        The case.

    Returns
    -------
    str
        Its validated scenario.
    """
    return case.scenario_yaml if case.scenario_yaml else dump_scenario(load_scenario())
