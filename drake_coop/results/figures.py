"""Figures 2–6 of the paper from a run's logs (PNG and SVG), and the reference figure.

===========================  ===================================================================
file                         content (panels as in the paper)
===========================  ===================================================================
``fig2_tracking_errors``     Cartesian tracking errors x̃, ỹ, z̃ (mm) of robot 1 (a–c) and
                             robot 2 (d–f)
``fig3_force_tracking``      measured squeeze λ (solid) against the desired λ_d (29) (dashed),
                             robots 1 (a) and 2 (b)
``fig4_force_estimate``      measured squeeze (solid) against the estimate λ̂ (22) (dashed)
``fig5_aux_force_error``     auxiliary force errors λ̂ − λ_d, robots 1 (a) and 2 (b)
``fig6_observation_errors``  observation errors z = q − q̂ (rad) of the three joints, robot 1
                             (a–c) and robot 2 (d–f)
``fig7_velocity_estimate``   velocity-estimate errors q̇ − q̇̂ (rad/s) of the three joints,
                             robot 1 (a–c) and robot 2 (d–f); only for logs holding ``qdot``
                             and ``qdot_hat`` (runs since issue 7)
``fig_references``           the designed references: x_d, y_d, z_d of each robot, the y_d–z_d
                             path and λ_d
===========================  ===================================================================

Phase boundaries are thin grey vertical lines, with the phase names above the top panels; a run
stopped early (diverged, interrupted) is drawn up to its last sample. Figures are drawn on
matplotlib's Agg canvas without pyplot: nothing is shown, no global backend is changed and no
figure outlives its function. Every file is written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from drake_coop.results.io import atomic_path

__all__ = ["fig_references", "plot_figures", "replot"]

WIDTH = 10.0
"""Figure width (in)."""
DPI = 120
"""Resolution of raster formats."""
SHORT = {"put_down": "down"}
"""Phase names shortened to fit above a panel."""

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


def _phases(ax: Axes, meta: dict, t_end: float | None, label: bool) -> None:
    """Grey lines at the phase boundaries up to ``t_end``; names above the axes if ``label``."""
    if t_end is None:
        return
    for name, a, b in meta["phases"]:
        if a >= t_end:
            break
        if a > 0:
            ax.axvline(a, color="0.6", lw=0.6, zorder=0)
        if label:   # above the y axis' offset text (×1e-6), below the title
            ax.annotate(SHORT.get(name, name), ((a + min(b, t_end)) / 2, 1.0),
                        xycoords=ax.get_xaxis_transform(), xytext=(0, 10),
                        textcoords="offset points", fontsize=6.5, color="0.35",
                        ha="center", va="bottom")


def _style(ax: Axes, title: str, ylabel: str, xlabel: str | None = "t [s]",
           top: bool = False, sci: tuple[int, int] | None = None) -> None:
    ax.set_title(title, fontsize=9, pad=20 if top else 4)
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
    return fig


def _letter(k: int) -> str:
    return f"({'abcdefghij'[k]})"


def _grid(logs: dict[str, Log], meta: dict, columns: list[tuple[str, str, Signal]],
          title: str, sci: tuple[int, int] | None = None) -> Figure:
    """Robots in rows, ``columns`` = ``(panel title, y label, signal)``; ``#`` in a panel title
    is the robot's number; ``sci`` = scientific-notation limits of the y tick labels."""
    robots = meta["robots"]
    fig, axes = _figure(len(robots), len(columns), 2.6 * len(robots))
    for i, robot in enumerate(robots):
        log, t_end = logs[robot], _t_end(logs[robot])
        last = i == len(robots) - 1
        for j, (label, ylabel, signal) in enumerate(columns):
            ax = axes[i, j]
            ax.plot(log["t"], signal(log), lw=0.8)
            _phases(ax, meta, t_end, label=i == 0)
            panel = f"{_letter(i * len(columns) + j)} " + label.replace("#", str(i + 1))
            _style(ax, panel, ylabel, "t [s]" if last else None, top=i == 0, sci=sci)
    return _finish(fig, title)


def _pair(logs: dict[str, Log], meta: dict, solid: tuple[str, str], dashed: tuple[str, str],
          ylabel: str, title: str) -> Figure:
    """One panel per robot: ``log[solid[0]]`` solid against ``log[dashed[0]]`` dashed."""
    robots = meta["robots"]
    fig, axes = _figure(1, len(robots), 3.4, sharex=False)
    for i, robot in enumerate(robots):
        log, ax = logs[robot], axes[0, i]
        ax.plot(log["t"], log[solid[0]], "-", lw=0.9, label=solid[1])
        ax.plot(log["t"], log[dashed[0]], "--", lw=0.9, label=dashed[1])
        _phases(ax, meta, _t_end(log), label=True)
        _style(ax, f"{_letter(i)} robot {i + 1}", ylabel, top=True)
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
                 formats: Iterable[str] = ("png", "svg")) -> list[Path]:
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

    Returns
    -------
    list of Path
        The files written, figure by figure in the order of the module docstring.

    Raises
    ------
    ValueError
        If a format is not supported by matplotlib (before anything is written).
    """
    formats = _check_formats(formats)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = {
        "fig2_tracking_errors": _grid(
            logs, meta,
            [(rf"$\tilde{{{c}}}_#$", rf"$\tilde{{{c}}}$ [mm]",
              _difference("x", "x_d", j, scale=1e3))
             for j, c in enumerate("xyz")],
            "Fig. 2 — tracking errors in Cartesian coordinates", sci=(-2, 3)),
        "fig3_force_tracking": _pair(
            logs, meta, ("lambda_meas", r"measured $\lambda$"),
            ("lambda_d", r"desired $\lambda_d$ (29)"), "F_x (squeeze) [N]",
            "Fig. 3 — measured force against the desired force"),
        "fig4_force_estimate": _pair(
            logs, meta, ("lambda_meas", r"measured $\lambda$"),
            ("lambda_hat", r"estimate $\hat\lambda$ (22)"), "F_x (squeeze) [N]",
            "Fig. 4 — measured force against its estimate"),
        "fig5_aux_force_error": _grid(
            logs, meta,
            [(r"robot #: $\hat\lambda_# - \lambda_{d#}$", r"$\hat\lambda - \lambda_d$ [N]",
              lambda log: log["lambda_hat"] - log["lambda_d"])],
            r"Fig. 5 — auxiliary force errors $\hat\lambda - \lambda_d$", sci=(-2, 3)),
        "fig6_observation_errors": _grid(
            logs, meta,
            [(f"$z_{{#{j + 1}}}$", f"$z_{j + 1}$ [rad]", _difference("q", "q_hat", j))
             for j in range(3)],
            r"Fig. 6 — observation errors $z = q - \hat q$", sci=(0, 0)),
    }
    if all("qdot" in logs[r] and "qdot_hat" in logs[r] for r in meta["robots"]):
        figures["fig7_velocity_estimate"] = _grid(
            logs, meta,
            [(f"$\\dot q_{{#{j + 1}}} - \\hat{{\\dot q}}_{{#{j + 1}}}$", "[rad/s]",
              _difference("qdot", "qdot_hat", j)) for j in range(3)],
            r"Velocity-estimate errors $\dot q - \hat{\dot q}$ (the controller's estimate)",
            sci=(-2, 3))
    paths = []
    for name, fig in figures.items():
        paths += _save(fig, out, name, formats)
    return paths


def fig_references(logs: dict[str, Log], meta: dict, out_dir: str | Path,
                   formats: Iterable[str] = ("png", "svg")) -> list[Path]:
    """Draw the designed references: x_d, y_d, z_d per robot, the y_d–z_d path and λ_d.

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
    robots = meta["robots"][:2]
    fig, axes = _figure(2, 2, 6.6, sharex=False)
    for i, robot in enumerate(robots):
        log, ax = logs[robot], axes[0, i]
        for j, c in enumerate("xyz"):
            ax.plot(log["t"], log["x_d"][:, j], lw=0.9, label=f"${c}_d$")
        _phases(ax, meta, _t_end(log), label=True)
        _style(ax, f"{_letter(i)} robot {i + 1}: desired position", "position [m]", top=True)
        ax.legend(fontsize=7, loc="best")
        style = "-" if i == 0 else "--"
        axes[1, 0].plot(log["x_d"][:, 1], log["x_d"][:, 2], style, lw=0.9,
                        label=f"robot {i + 1}")
        axes[1, 1].plot(log["t"], log["lambda_d"], style, lw=0.9, label=f"robot {i + 1}")
    _style(axes[1, 0], r"(c) path in the $y$–$z$ plane", "$z_d$ [m]", "$y_d$ [m]")
    axes[1, 0].set_aspect("equal", adjustable="datalim")
    t_end = max((t for t in (_t_end(logs[r]) for r in robots) if t is not None), default=None)
    _phases(axes[1, 1], meta, t_end, label=False)
    _style(axes[1, 1], r"(d) desired squeeze $\lambda_d$ (29)", r"$\lambda_d$ [N]")
    for ax in axes[1]:
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
        Figures 2–6, the reference figure (PNG and SVG) and ``metrics.json``.

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
    return paths
