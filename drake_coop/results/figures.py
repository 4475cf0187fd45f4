"""Figures 2–6 of the paper from a run's logs (PNG and SVG), and the reference figure.

===========================  ===================================================================
file                         content (panels as in the paper; one row or panel per robot)
===========================  ===================================================================
``fig2_tracking_errors``     Cartesian tracking errors x̃, ỹ, z̃ (µm) of robot 1 (a–c),
                             robot 2 (d–f), …
``fig3_force_tracking``      measured squeeze λ (solid) against the desired λ_d (29) (dashed),
                             robots 1 (a), 2 (b), …
``fig4_force_estimate``      measured squeeze (solid) against the estimate λ̂ (22) (dashed)
``fig5_aux_force_error``     auxiliary force errors λ̂ − λ_d (mN), robots 1 (a), 2 (b), …
``fig6_observation_errors``  observation errors z = q − q̂ (µrad), one panel per joint: robot 1
                             (a–c), robot 2 (d–f), … for the paper's 3-joint arms
``fig_force_errors``         ours: the headline errors on their own scale, squeeze tracking
                             λ − λ_d and force observer λ − λ̂ (mN), one row per robot
                             (Figures 3–4 overlay λ on a 0–50 N scale, where 0.05 N is a line)
``fig7_velocity_estimate``   Fig. 7 (ours): velocity-estimate errors q̇ − q̇̂ (mrad/s) per
                             joint, laid out as Fig. 6; only for logs holding ``qdot`` and
                             ``qdot_hat`` (runs with the sensing models)
``fig_object_mass``          the object's mass as the controllers know it: each robot's share
                             m̂_i and their sum (kg), against the true mass (dashed) on a
                             plant with a body; only for logs holding ``mass_share``
                             (``object_model`` known or estimated)
``fig_references``           the designed references: x_d, y_d, z_d of each robot, the path
                             (in the y–z plane for the paper, see :func:`path_plane`) and λ_d
===========================  ===================================================================

Any number of robots, joints n_i and constraints m_i: the joint figures have max n_i columns
(a robot with fewer joints leaves its last panels out); a force of m >= 2 constraints draws
each row λ_1 … λ_m (one colour per row, with a legend); the squeeze axis is labelled ``F_x``
when λ = ±F_x (the paper's normals ±e_x), λ otherwise; the reference figure draws robot i in
colour ``C{i}`` with its own line style. For the paper (two robots, n = 3, m = 1) the figures
keep their layout. Units are those a reader reads: each figure takes the first of µm / mm / m
(µrad / mrad / rad, mN / N, mrad/s / rad/s) in which its largest value is below 1000, one
unit for all its panels, and the labels carry the robot's index (:math:`z_{i,j}`: robot i,
joint j).

Phase boundaries are thin grey vertical lines, with the phase names above the top panels (a
name that would overlap its neighbour, as measured once drawn, raised a row); a run
stopped early (diverged, interrupted) is drawn up to its last sample. Figures are drawn on
matplotlib's Agg canvas without pyplot: nothing is shown, no global backend is changed and no
figure outlives its function. Every file is written atomically.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Iterable

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from drake_coop.results.io import atomic_path

__all__ = ["fig_references", "plot_figures", "replot"]

WIDTH = 10.0
"""Figure width (in)."""
DPI = 120
"""Resolution of raster formats."""
#: Units of the figures, smallest first: (factor from SI, name). A figure takes the first unit
#: in which its largest value is below 1000, one unit for all its panels.
LENGTH_UNITS = ((1e6, "µm"), (1e3, "mm"), (1.0, "m"))
FORCE_UNITS = ((1e3, "mN"), (1.0, "N"))
ANGLE_UNITS = ((1e6, "µrad"), (1e3, "mrad"), (1.0, "rad"))
RATE_UNITS = ((1e3, "mrad/s"), (1.0, "rad/s"))

Log = dict[str, np.ndarray]
Signal = Callable[[Log], np.ndarray]


def _figure(nrows: int, ncols: int, height: float, sharex: bool = True
            ) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=(WIDTH, height), dpi=DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=False)
    return fig, axes


def _t_end(log: Log) -> float | None:
    """Last finite sample time, None for an empty log."""
    t = np.asarray(log["t"], dtype=float)
    t = t[np.isfinite(t)]
    return float(t.max()) if t.size else None


def _phases(ax: Axes, meta: dict, t_end: float | None, label: bool,
            narrow: bool = False) -> None:
    """Grey lines at the phase boundaries up to ``t_end``; names above the axes if ``label``,
    the names of ``run.json`` and ``metrics.json`` (``put_down``), on two alternating heights
    when ``narrow`` so that neighbours do not overlap."""
    if t_end is None:
        return
    for k, (name, a, b) in enumerate(meta["phases"]):
        if a >= t_end:
            break
        if a > 0:
            ax.axvline(a, color="0.6", lw=0.6, zorder=0)
        if label:   # above the y axis' offset text (×1e-6), below the title
            ax.annotate(name, ((a + min(b, t_end)) / 2, 1.0),
                        xycoords=ax.get_xaxis_transform(),
                        xytext=(0, 18 if narrow and k % 2 else 10),
                        textcoords="offset points", fontsize=6.5, color="0.35",
                        ha="center", va="bottom", gid=PHASE_LABEL)


#: ``gid`` of the phase names drawn by :func:`_phases` (:func:`_unstack_phase_labels`).
PHASE_LABEL = "phase_label"
#: The least horizontal gap (points) between two phase names on one row.
LABEL_GAP_PT = 3.0


def _widened(box: Bbox, pad: float) -> Bbox:
    """``box`` widened by ``pad`` pixels left and right (not up and down: rows stay close)."""
    return Bbox.from_extents(box.x0 - pad, box.y0, box.x1 + pad, box.y1)


def _unstack_phase_labels(fig: Figure, step: float = 8.0, levels: int = 4) -> None:
    """Raise a phase name that, as drawn, overlaps a neighbour of its panel by ``step`` points
    until it overlaps none (at most ``levels`` rows). Short phases on a narrow panel
    (``put_down`` and ``return``, 10 s and 15 s of the paper's 90 s run, on a third of the
    page's width) would print their names over each other; the measured text extents
    decide, whatever the run's timeline or the panel's width."""
    renderer = fig.canvas.get_renderer()
    gap = LABEL_GAP_PT * fig.dpi / 72.0        # names that merely touch read as one word
    for ax in fig.axes:
        labels = [t for t in ax.texts if t.get_gid() == PHASE_LABEL]
        placed = []
        for text in labels:
            x, y0 = text.xyann
            for level in range(levels):
                text.xyann = (x, y0 + step * level)
                box = _widened(text.get_window_extent(renderer), gap / 2)
                if not any(box.overlaps(other) for other in placed):
                    break
            placed.append(_widened(text.get_window_extent(renderer), gap / 2))
        if labels:   # the title above the highest row of names (pads in points)
            top = max(t.get_window_extent(renderer).y1 for t in labels)
            needed = (top - ax.get_window_extent(renderer).y1) * 72.0 / fig.dpi + 3.0
            current = ax.titleOffsetTrans.get_matrix()[1, 2] * 72.0 / fig.dpi
            if needed > current:
                ax.set_title(ax.get_title(), fontsize=ax.title.get_fontsize(), pad=needed)


def _style(ax: Axes, title: str, ylabel: str, xlabel: str | None = "t [s]",
           top: bool = False, sci: tuple[int, int] | None = None, narrow: bool = False
           ) -> None:
    ax.set_title(title, fontsize=9, pad=(28 if narrow else 20) if top else 4)
    ax.set_ylabel(ylabel, fontsize=8)
    if xlabel:
        ax.set_xlabel(xlabel, fontsize=8)
    ax.grid(True, lw=0.3)
    ax.tick_params(labelsize=7)
    ax.ticklabel_format(axis="y", useOffset=False)   # values as they are, no "+1.5e-3"
    if sci is not None:
        ax.ticklabel_format(axis="y", style="sci", scilimits=sci)
        ax.yaxis.get_offset_text().set_fontsize(7)


def _finish(fig: Figure, title: str) -> Figure:
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    _unstack_phase_labels(fig)
    fig.tight_layout()
    return fig


def _letter(k: int) -> str:
    """Panel label ``(a)``, ``(b)``, …, ``(z)``, then ``(aa)``, ``(ab)``, …"""
    letters = "abcdefghijklmnopqrstuvwxyz"
    return f"({letters[k]})" if k < 26 else f"({letters[k // 26 - 1]}{letters[k % 26]})"


def _components(ax: Axes, t: np.ndarray, y: np.ndarray, symbol: str, **style) -> None:
    """Plot ``y`` (N,) as one line, or (N, m) as m lines labelled ``symbol`` with the index
    ``1..m`` as subscript (``symbol`` holds ``{k}`` where the index goes)."""
    y = np.asarray(y)
    if y.ndim == 1:
        ax.plot(t, y, **style)
        return
    for k in range(y.shape[1]):
        ax.plot(t, y[:, k], label=symbol.format(k=k + 1), **style)


def _unit(values: Iterable[np.ndarray], units: tuple[tuple[float, str], ...]
          ) -> tuple[float, str]:
    """The first ``(factor, unit)`` of ``units`` in which the largest finite ``|value|`` is
    below 1000 (the last unit if none)."""
    peak = 0.0
    for v in values:
        v = np.abs(np.asarray(v, dtype=float))
        v = v[np.isfinite(v)]
        if v.size:
            peak = max(peak, float(v.max()))
    return next(((f, u) for f, u in units if peak * f < 1000), units[-1])


def _grid(logs: dict[str, Log], meta: dict,
          columns: list[tuple[str, str, Signal]] | Callable[[Log], list[tuple[str, str, Signal]]],
          title: str, units: tuple[tuple[float, str], ...], symbol: str = "") -> Figure:
    """Robots in rows, ``columns`` = ``(panel title, y label, signal)`` (or a function of the
    robot's log giving them, e.g. one per joint); ``#`` in a panel title or y label is the
    robot's number and ``{unit}`` in a y label the unit chosen from ``units`` (SI signals,
    one unit for the whole figure, see :func:`_unit`). A signal of shape (N, m) draws m
    lines with a legend (``symbol`` with ``{k}`` for the index). A robot with fewer columns than
    the widest leaves its last panels out."""
    robots = meta["robots"]
    per_robot = [columns(logs[r]) if callable(columns) else columns for r in robots]
    ncols = max(len(c) for c in per_robot)
    values = [[signal(logs[r]) for _, _, signal in per_robot[i]] for i, r in enumerate(robots)]
    factor, unit = _unit((v for row in values for v in row), units)
    narrow = ncols > 3
    fig, axes = _figure(len(robots), ncols, 2.6 * len(robots) + (0.2 if narrow else 0.0))
    for i, robot in enumerate(robots):
        log, t_end = logs[robot], _t_end(logs[robot])
        for j in range(ncols):
            ax = axes[i, j]
            if j >= len(per_robot[i]):
                ax.set_visible(False)
                continue
            label, ylabel, _ = per_robot[i][j]
            # The x axis' labels go under the lowest drawn panel of each column.
            last = all(j >= len(per_robot[k]) for k in range(i + 1, len(robots)))
            y = factor * np.asarray(values[i][j], dtype=float)
            _components(ax, log["t"], y, symbol, lw=0.8)
            _phases(ax, meta, t_end, label=i == 0, narrow=narrow)
            panel = f"{_letter(i * ncols + j)} " + label.replace("#", str(i + 1))
            _style(ax, panel, ylabel.replace("#", str(i + 1)).replace("{unit}", unit),
                   "t [s]" if last else None, top=i == 0, narrow=narrow)
            if last:
                ax.xaxis.set_tick_params(labelbottom=True)
            if np.ndim(y) == 2:
                ax.legend(fontsize=7, loc="upper right")
    return _finish(fig, title)


def _squeeze_label(log: Log) -> str:
    """The y label of the squeeze: ``F_x`` when the logged λ is ``±F_x`` (the paper's normals
    ``±e_x``), else λ (another normal, or m >= 2 constraints)."""
    lam, F = np.asarray(log["lambda_meas"], dtype=float), np.asarray(log["F_meas"], dtype=float)
    if lam.ndim == 1:
        ok = np.isfinite(lam) & np.isfinite(F[:, 0])
        if np.allclose(np.abs(lam[ok]), np.abs(F[ok, 0]), rtol=1e-9, atol=1e-9):
            return "F_x (squeeze) [N]"
        return r"$\lambda$ (squeeze) [N]"
    return r"$\lambda$ [N]"


def _pair(logs: dict[str, Log], meta: dict, solid: tuple[str, str, str],
          dashed: tuple[str, str, str], title: str) -> Figure:
    """One panel per robot: ``log[solid[0]]`` solid against ``log[dashed[0]]`` dashed, labelled
    ``solid[1]`` and ``dashed[1]``; for m >= 2 constraints, one colour per row ``k`` of the
    force, labelled ``solid[2]`` and ``dashed[2]`` with ``{k}`` the subscript 1..m."""
    robots = meta["robots"]
    fig, axes = _figure(1, len(robots), 3.4, sharex=False)
    for i, robot in enumerate(robots):
        log, ax = logs[robot], axes[0, i]
        a, b = np.asarray(log[solid[0]]), np.asarray(log[dashed[0]])
        if a.ndim == 1:
            ax.plot(log["t"], a, "-", lw=0.9, label=solid[1])
            ax.plot(log["t"], b, "--", lw=0.9, label=dashed[1])
        else:
            for k in range(a.shape[1]):
                colour = f"C{k % 10}"
                ax.plot(log["t"], a[:, k], "-", lw=0.9, color=colour,
                        label=solid[2].format(k=k + 1))
                ax.plot(log["t"], b[:, k], "--", lw=0.9, color=colour,
                        label=dashed[2].format(k=k + 1))
        _phases(ax, meta, _t_end(log), label=True)
        _style(ax, f"{_letter(i)} robot {i + 1}", _squeeze_label(log), top=True)
        ax.legend(fontsize=7, loc="upper right")
    return _finish(fig, title)


def _save(fig: Figure, out_dir: Path, name: str, formats: Iterable[str]) -> list[Path]:
    paths = []
    try:
        for fmt in formats:
            path = out_dir / f"{name}.{fmt}"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format=fmt, dpi=DPI)
            paths.append(path)
    finally:
        fig.clear()
    return paths


def _check_formats(formats: Iterable[str]) -> tuple[str, ...]:
    formats = tuple(formats)
    supported = FigureCanvasAgg(Figure()).get_supported_filetypes()
    unknown = [f for f in formats if f not in supported]
    if unknown:
        raise ValueError(f"unsupported figure formats {unknown}; use some of {sorted(supported)}")
    return formats


def _difference(key: str, other: str, j: int, scale: float = 1.0) -> Signal:
    """``scale * (log[key][:, j] - log[other][:, j])``."""
    return lambda log: scale * (log[key][:, j] - log[other][:, j])


def plot_figures(logs: dict[str, Log], meta: dict, out_dir: str | Path,
                 formats: Iterable[str] = ("png", "svg"),
                 only: Iterable[str] | None = None) -> list[Path]:
    """Draw Figures 2–6 of the paper into ``out_dir``.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` (schema of :mod:`drake_coop.results.logs`); may end early and
        hold NaN (a diverged run).
    meta : dict
        Run metadata; ``robots`` (row order) and ``phases`` are used.
    out_dir : str or Path
        Output directory; created if needed.
    formats : iterable of str
        File formats, each one file per figure (``"png"``, ``"svg"``, ``"pdf"``, ...).
    only : iterable of str, optional
        Draw only these figures (their file names without suffix); None: every figure the
        logs hold data for.

    Returns
    -------
    list of Path
        The files written, figure by figure in the order of the module docstring.

    Raises
    ------
    ValueError
        If a format is not supported by matplotlib, or ``only`` names a figure these logs do
        not draw (before anything is written).
    """
    formats = _check_formats(formats)
    out = Path(out_dir)

    def joints(key: str, other: str, title: str, ylabel: str):
        """One column per joint of the robot: ``log[key] − log[other]``."""
        return lambda log: [(title.format(j=j + 1), ylabel.format(j=j + 1),
                             _difference(key, other, j)) for j in range(log[key].shape[1])]

    figures = {
        "fig2_tracking_errors": lambda: _grid(
            logs, meta,
            # (z - z_d)_i, not the paper's z-tilde: z is the observer's q - q-hat (Fig. 6)
            [(rf"$({c} - {c}_d)_#$", rf"$({c} - {c}_d)_#$ [{{unit}}]", _difference("x", "x_d", j))
             for j, c in enumerate("xyz")],
            "Fig. 2 — tracking errors in Cartesian coordinates", LENGTH_UNITS),
        "fig3_force_tracking": lambda: _pair(
            logs, meta, ("lambda_meas", r"measured $\lambda$", r"measured $\lambda_{k}$"),
            ("lambda_d", r"desired $\lambda_d$ (29)", r"desired $\lambda_{{d{k}}}$ (29)"),
            "Fig. 3 — measured force against the desired force"),
        "fig4_force_estimate": lambda: _pair(
            logs, meta, ("lambda_meas", r"measured $\lambda$", r"measured $\lambda_{k}$"),
            ("lambda_hat", r"estimate $\hat\lambda$ (22)", r"estimate $\hat\lambda_{k}$ (22)"),
            "Fig. 4 — measured force against its estimate"),
        "fig5_aux_force_error": lambda: _grid(
            logs, meta,
            # The robot's number as subscript for one constraint (the paper), the rows' numbers
            # (legend) for several.
            lambda log: [(r"robot #: $\hat\lambda_# - \lambda_{d#}$"
                          if log["lambda_d"].ndim == 1 else r"robot #: $\hat\lambda - \lambda_d$",
                          r"$\hat\lambda_# - \lambda_{d#}$ [{unit}]"
                          if log["lambda_d"].ndim == 1 else r"$\hat\lambda - \lambda_d$ [{unit}]",
                          lambda log: log["lambda_hat"] - log["lambda_d"])],
            r"Fig. 5 — auxiliary force errors $\hat\lambda - \lambda_d$", FORCE_UNITS,
            symbol=r"$\hat\lambda_{k} - \lambda_{{d{k}}}$"),
        "fig6_observation_errors": lambda: _grid(
            logs, meta, joints("q", "q_hat", "$z_{{#,{j}}}$", "$z_{{#,{j}}}$ [{{unit}}]"),
            r"Fig. 6 — observation errors $z = q - \hat q$ (robot, joint)", ANGLE_UNITS),
        "fig_force_errors": lambda: _grid(
            logs, meta,
            [(r"robot #: squeeze tracking $\lambda - \lambda_d$",
              r"$\lambda - \lambda_d$ [{unit}]",
              lambda log: log["lambda_meas"] - log["lambda_d"]),
             (r"robot #: force observer $\lambda - \hat\lambda$",
              r"$\lambda - \hat\lambda$ [{unit}]",
              lambda log: log["lambda_meas"] - log["lambda_hat"])],
            r"Force errors (the headline numbers): $\lambda - \lambda_d$ and "
            r"$\lambda - \hat\lambda$", FORCE_UNITS, symbol=r"$\lambda_{k}$"),
    }
    if all("qdot" in logs[r] and "qdot_hat" in logs[r] for r in meta["robots"]):
        figures["fig7_velocity_estimate"] = lambda: _grid(
            logs, meta,
            joints("qdot", "qdot_hat", "$\\dot q_{{#,{j}}} - \\hat{{\\dot q}}_{{#,{j}}}$",
                   "$\\dot q_{{#,{j}}} - \\hat{{\\dot q}}_{{#,{j}}}$ [{{unit}}]"),
            r"Fig. 7 — velocity-estimate errors $\dot q - \hat{\dot q}$ (robot, joint)",
            RATE_UNITS)
    if all("mass_share" in logs[r] for r in meta["robots"]):
        figures["fig_object_mass"] = lambda: _object_mass(logs, meta)
    if only is not None:
        only = set(only)
        if only - set(figures):
            raise ValueError(f"only: {', '.join(sorted(only - set(figures)))} not among the "
                             f"figures these logs draw ({', '.join(figures)})")
        figures = {name: draw for name, draw in figures.items() if name in only}
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, draw in figures.items():       # drawn one at a time: one figure open at once
        paths += _save(draw(), out, name, formats)
    return paths


def _object_mass(logs: dict[str, Log], meta: dict) -> Figure:
    """Each robot's mass share ``m̂_i`` and their sum against time (the estimate's
    convergence with ``object_model: estimated``)."""
    fig, axes = _figure(1, 1, 3.0)
    ax = axes[0, 0]
    robots = meta["robots"]
    total = None
    for i, r in enumerate(robots):
        log = logs[r]
        ax.plot(log["t"], log["mass_share"], color=f"C{i}", lw=0.9, label=rf"$\hat m_{i + 1}$")
        total = log["mass_share"] if total is None else total + log["mass_share"]
    t = logs[robots[0]]["t"]
    ax.plot(t, total, color="k", lw=1.0, label=r"$\sum_i \hat m_i$")
    true_mass = meta.get("object_mass") if meta.get("object_size") is not None else None
    if true_mass is not None:   # a body on the plant: the truth the sum should reach
        ax.axhline(float(true_mass), color="0.3", lw=0.9, ls="--",
                   label=f"true mass m = {float(true_mass):g} kg")
    _phases(ax, meta, _t_end(logs[robots[0]]), label=True)
    _style(ax, "", "mass [kg]", top=True)
    ax.legend(fontsize=7, loc="best")
    return _finish(fig, "The object's mass as the controllers know it (shares and sum)")


#: Line styles of the robots in the shared panels of the reference figure (robot i: colour
#: ``C{i}`` and style ``STYLES[i mod 4]``).
STYLES = ("-", "--", "-.", ":")
AXES = "xyz"


def path_plane(logs: dict[str, Log], robots: list[str], tol: float = 1e-9) -> tuple[int, int]:
    """The two Cartesian axes (indices, increasing) of the plane in which to draw the paths.

    The axes of the two largest extents ``max_i (max x_d − min x_d)`` of the robots' desired
    paths while they hold the object (samples with ``λ_d ≠ 0``; all samples if none), extents
    within ``tol`` (m) of each other counted equal and ties broken in the order y, z, x. The
    paper's path (a circle in the y–z plane, lift and put-down along z) gives ``(1, 2)``, the
    y–z plane; a path along z only gives the y–z plane too.

    Parameters
    ----------
    logs : dict of str to Log
        The robots' logs.
    robots : list of str
        The robots drawn.
    tol : float
        Extents within this of each other are equal, m.

    Returns
    -------
    tuple of int
        The two axes (0 x, 1 y, 2 z).
    """
    extent = np.zeros(3)
    for r in robots:
        x_d, lam_d = np.asarray(logs[r]["x_d"], dtype=float), np.asarray(logs[r]["lambda_d"])
        held = np.any(np.reshape(lam_d, (len(lam_d), -1)) != 0, axis=1)
        points = x_d[held] if held.any() else x_d
        points = points[np.isfinite(points).all(axis=1)]
        if len(points):
            extent = np.maximum(extent, np.ptp(points, axis=0))
    preference = (1, 2, 0)
    ranked = sorted(preference, key=lambda j: (-np.round(extent[j] / tol),
                                               preference.index(j)))
    return tuple(sorted(ranked[:2]))


def fig_references(logs: dict[str, Log], meta: dict, out_dir: str | Path,
                   formats: Iterable[str] = ("png", "svg")) -> list[Path]:
    """Draw the designed references: x_d, y_d, z_d per robot, the path and λ_d.

    The top row has one panel per robot (x_d, y_d, z_d against time); below, the robots' paths
    in the plane of their two largest extents (:func:`path_plane`; the y–z plane for the
    paper) and their desired squezes λ_d (every row λ_{d,k} for m >= 2), robot i drawn in
    colour ``C{i}`` with line style :data:`STYLES` ``[i mod 4]``.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` (schema of :mod:`drake_coop.results.logs`).
    meta : dict
        Run metadata; ``robots`` and ``phases`` are used.
    out_dir : str or Path
        Output directory; created if needed.
    formats : iterable of str
        File formats.

    Returns
    -------
    list of Path
        ``fig_references.<format>`` for each format.
    """
    formats = _check_formats(formats)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    robots = meta["robots"]
    l = len(robots)
    width = math.lcm(l, 2)        # top row: l panels; bottom row: 2 panels
    fig = Figure(figsize=(WIDTH, 6.6), dpi=DPI)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, width)
    top = [fig.add_subplot(grid[0, i * width // l:(i + 1) * width // l]) for i in range(l)]
    path_ax = fig.add_subplot(grid[1, :width // 2])
    force_ax = fig.add_subplot(grid[1, width // 2:])
    u, v = path_plane(logs, robots)
    for i, robot in enumerate(robots):
        log, ax = logs[robot], top[i]
        for j, c in enumerate(AXES):
            ax.plot(log["t"], log["x_d"][:, j], lw=0.9, label=f"${c}_d$")
        _phases(ax, meta, _t_end(log), label=True)
        _style(ax, f"{_letter(i)} robot {i + 1}: desired position", "position [m]", top=True)
        ax.legend(fontsize=7, loc="best")
        style = {"ls": STYLES[i % len(STYLES)], "color": f"C{i % 10}", "lw": 0.9}
        path_ax.plot(log["x_d"][:, u], log["x_d"][:, v], label=f"robot {i + 1}", **style)
        lam_d = np.asarray(log["lambda_d"])
        if lam_d.ndim == 1:
            force_ax.plot(log["t"], lam_d, label=f"robot {i + 1}", **style)
        else:
            for k in range(lam_d.shape[1]):
                force_ax.plot(log["t"], lam_d[:, k],
                              label=rf"robot {i + 1}: $\lambda_{{d{k + 1}}}$",
                              **{**style, "color": f"C{(i + k * l) % 10}"})
    _style(path_ax, rf"{_letter(l)} path in the ${AXES[u]}$–${AXES[v]}$ plane",
           f"${AXES[v]}_d$ [m]", f"${AXES[u]}_d$ [m]")
    path_ax.set_aspect("equal", adjustable="datalim")
    t_end = max((t for t in (_t_end(logs[r]) for r in robots) if t is not None), default=None)
    _phases(force_ax, meta, t_end, label=False)
    _style(force_ax, rf"{_letter(l + 1)} desired squeeze $\lambda_d$ (29)", r"$\lambda_d$ [N]")
    for ax in (path_ax, force_ax):
        ax.legend(fontsize=7, loc="best")
    _finish(fig, "Reference trajectories: quintic rest-to-rest segments, circle (28), "
                 "force (29)")
    return _save(fig, out, "fig_references", formats)


def replot(out_dir: str | Path) -> list[Path]:
    """Redraw the figures and the metrics of a run directory from its logs.

    Parameters
    ----------
    out_dir : str or Path
        A run directory written by :func:`~drake_coop.results.logs.save_logs`.

    Returns
    -------
    list of Path
        Figures 2–6, the reference figure (PNG and SVG), ``metrics.json`` and the block
        diagrams' ``.svg`` that the run could not draw (graphviz installed since).

    Raises
    ------
    FileNotFoundError, ValueError
        If the logs are missing or malformed (from :func:`~drake_coop.results.logs.load_logs`).
    """
    from drake_coop.results.logs import load_logs
    from drake_coop.results.metrics import compute_metrics, write_metrics

    logs, meta = load_logs(out_dir)
    paths = plot_figures(logs, meta, out_dir)
    paths += fig_references(logs, meta, out_dir)
    paths.append(write_metrics(out_dir, compute_metrics(logs, meta)))
    from drake_coop.results.export import draw_missing_svgs

    paths += draw_missing_svgs(out_dir)
    return paths
