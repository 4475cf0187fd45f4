"""Figures 2–6 of the paper from a run's logs (PNG and SVG), and the reference figure.

====================  ========================================================================
file                  content (panels as in the paper)
====================  ========================================================================
``fig2_*``            Cartesian tracking errors x̃, ỹ, z̃ of robot 1 (a–c) and robot 2 (d–f)
``fig3_*``            measured squeeze F_x against the desired force (29), robots 1 and 2
``fig4_*``            measured squeeze against the estimate λ̂ of the force observer (22)
``fig5_*``            auxiliary force errors λ̂ − λ_d
``fig6_*``            observation errors z = q − q̂ of the three joints of both robots
``fig_references``    the designed reference paths x_d, y_d, z_d, the y–z circle and λ_d
====================  ========================================================================

Phase boundaries are drawn as thin grey lines, named on the top panels.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drake_coop.results.io import atomic_path  # noqa: E402

LETTERS = "abcdef"


SHORT = {"put_down": "down"}


def _phases(ax, meta, label: bool, t_end: float | None = None) -> None:
    for name, a, b in meta["phases"]:
        if t_end is not None and a >= t_end:
            break
        if a > 0:
            ax.axvline(a, color="0.6", lw=0.6, zorder=0)
        if label:
            mid = (a + min(b, t_end if t_end is not None else b)) / 2
            ax.text(mid, 1.02, SHORT.get(name, name), transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=6.5, color="0.35")


def _save(fig, out_dir: Path, name: str, formats) -> list[Path]:
    paths = []
    for fmt in formats:
        path = out_dir / f"{name}.{fmt}"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=120)
        paths.append(path)
    plt.close(fig)
    return paths


def _grid(logs, meta, series, ylabel, title, scale=1.0, sci=False):
    """2 rows (robots) × len(series) columns of time plots."""
    robots = meta["robots"]
    ncol = len(series)
    fig, axes = plt.subplots(len(robots), ncol, figsize=(10, 2.6 * len(robots)), sharex=True,
                             squeeze=False)
    for i, robot in enumerate(robots):
        log = logs[robot]
        for j, (label, fn) in enumerate(series):
            ax = axes[i, j]
            ax.plot(log["t"], scale * fn(log), lw=0.8)
            _phases(ax, meta, label=(i == 0), t_end=float(log["t"][-1]))
            ax.set_title(f"{LETTERS[i * ncol + j]}) {label.format(i=i + 1)}", fontsize=9,
                         pad=12 if i == 0 else 4)
            ax.set_ylabel(ylabel, fontsize=8)
            ax.grid(True, lw=0.3)
            ax.tick_params(labelsize=7)
            if sci:
                ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
            if i == len(robots) - 1:
                ax.set_xlabel("t [s]", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def _pair(logs, meta, solid, dashed, ylabel, title):
    robots = meta["robots"]
    fig, axes = plt.subplots(1, len(robots), figsize=(10, 3.4), squeeze=False)
    for i, robot in enumerate(robots):
        log, ax = logs[robot], axes[0, i]
        ax.plot(log["t"], log[solid[0]], lw=0.9, label=solid[1])
        ax.plot(log["t"], log[dashed[0]], "--", lw=0.9, label=dashed[1])
        _phases(ax, meta, label=True, t_end=float(log["t"][-1]))
        ax.set_title(f"{LETTERS[i]}) robot {i + 1}", fontsize=9, pad=12)
        ax.set_xlabel("t [s]", fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(True, lw=0.3)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_figures(logs: dict, meta: dict, out_dir: str | Path,
                 formats: tuple[str, ...] = ("png", "svg")) -> list[Path]:
    """Draw Figures 2–6 of the paper into ``out_dir``; returns the files written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    # Millimetres as in the paper, micrometres when the errors are that small.
    worst = max(float(np.nanmax(np.abs(logs[r]["x"] - logs[r]["x_d"]), initial=0.0))
                for r in meta["robots"])
    unit, scale = ("µm", 1e6) if worst < 1e-4 else ("mm", 1e3)
    fig = _grid(logs, meta, [("x̃{i}", lambda l: l["x"][:, 0] - l["x_d"][:, 0]),
                             ("ỹ{i}", lambda l: l["x"][:, 1] - l["x_d"][:, 1]),
                             ("z̃{i}", lambda l: l["x"][:, 2] - l["x_d"][:, 2])],
                f"error [{unit}]", "Fig. 2 — tracking errors in Cartesian coordinates",
                scale=scale)
    paths += _save(fig, out, "fig2_tracking_errors", formats)
    fig = _pair(logs, meta, ("lambda_meas", "measured"), ("lambda_d", "desired (29)"),
                "F_x (squeeze) [N]", "Fig. 3 — measured force against the desired force")
    paths += _save(fig, out, "fig3_force_tracking", formats)
    fig = _pair(logs, meta, ("lambda_meas", "measured"), ("lambda_hat", "estimate λ̂ (22)"),
                "F_x (squeeze) [N]", "Fig. 4 — measured force against the estimate")
    paths += _save(fig, out, "fig4_force_estimate", formats)
    fig = _grid(logs, meta, [("robot {i}: λ̂{i} − λd{i}",
                              lambda l: l["lambda_hat"] - l["lambda_d"])],
                "[N]", "Fig. 5 — auxiliary force errors λ̂ − λ_d", sci=True)
    paths += _save(fig, out, "fig5_aux_force_error", formats)
    fig = _grid(logs, meta, [(f"z{{i}}{j + 1}", (lambda j: lambda l: l["q"][:, j]
                                                  - l["q_hat"][:, j])(j)) for j in range(3)],
                "[rad]", "Fig. 6 — observation errors z = q − q̂", sci=True)
    paths += _save(fig, out, "fig6_observation_errors", formats)
    return paths


def fig_references(logs: dict, meta: dict, out_dir: str | Path,
                   formats: tuple[str, ...] = ("png", "svg")) -> list[Path]:
    """The designed references: x_d, y_d, z_d of both robots, the y–z path and λ_d."""
    robots = meta["robots"]
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.4))
    for i, robot in enumerate(robots):
        log = logs[robot]
        for j, c in enumerate("xyz"):
            axes[0, 0].plot(log["t"], log["x_d"][:, j], lw=0.9,
                            ls="-" if i == 0 else "--", label=f"{c}_d{i + 1}")
        axes[0, 1].plot(log["x_d"][:, 1], log["x_d"][:, 2], lw=0.9, ls="-" if i == 0 else "--",
                        label=f"robot {i + 1}")
        axes[1, 0].plot(log["t"], log["lambda_d"], lw=0.9, ls="-" if i == 0 else "--",
                        label=f"λ_d{i + 1}")
        axes[1, 1].plot(log["t"], np.degrees(log["q_d"]), lw=0.8, ls="-" if i == 0 else "--")
    for ax in (axes[0, 0], axes[1, 0], axes[1, 1]):
        _phases(ax, meta, label=ax is axes[0, 0])
        ax.set_xlabel("t [s]", fontsize=8)
    axes[0, 0].set_ylabel("desired position [m]", fontsize=8)
    axes[0, 1].set_xlabel("y_d [m]", fontsize=8)
    axes[0, 1].set_ylabel("z_d [m]", fontsize=8)
    axes[0, 1].set_aspect("equal", adjustable="datalim")
    axes[1, 0].set_ylabel("desired squeeze (29) [N]", fontsize=8)
    axes[1, 1].set_ylabel("q_d [deg] (solid: robot 1)", fontsize=8)
    for ax in axes.flat:
        ax.grid(True, lw=0.3)
        ax.tick_params(labelsize=7)
    for ax in (axes[0, 0], axes[0, 1], axes[1, 0]):
        ax.legend(fontsize=7, ncol=2)
    fig.suptitle("Reference trajectories: quintic rest-to-rest segments, circle (28), force (29)",
                 fontsize=10)
    fig.tight_layout()
    return _save(fig, Path(out_dir), "fig_references", formats)


def replot(out_dir: str | Path) -> list[Path]:
    """Redraw figures and metrics of a run directory from its logs."""
    from drake_coop.results.logs import load_logs
    from drake_coop.results.metrics import compute_metrics, write_metrics

    logs, meta = load_logs(out_dir)
    paths = plot_figures(logs, meta, out_dir)
    paths += fig_references(logs, meta, out_dir)
    paths.append(write_metrics(out_dir, compute_metrics(logs, meta)))
    return paths
