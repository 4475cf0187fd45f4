"""``pacing.png``: the paced run's figures (:mod:`drake_coop.robot.pacing`) as histograms and
time series, readable with outliers: each axis ends at a high percentile of its values (or the
delay margin), and the ticks beyond are marked at the edge and counted, so that one late tick
(a 181 ms pause) does not flatten the millisecond behaviour into a line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


#: The plot's axes end at this percentile of a figure (times :data:`CLIP_HEADROOM`); the
#: ticks beyond are drawn at the edge and counted in the axes' title.
CLIP_PERCENTILE = 99.9
#: Headroom above the clipping percentile.
CLIP_HEADROOM = 1.5


def clip_limit(values_s: np.ndarray, margin_s: float | None = None) -> float:
    """Where ``pacing.png`` ends an axis of these values (s): :data:`CLIP_HEADROOM` times
    their :data:`CLIP_PERCENTILE`-th percentile, and at least the delay margin's (so that
    its line shows); one late tick does not flatten the rest.

    Parameters
    ----------
    values_s : numpy.ndarray
        The values, s.
    margin_s : float or None
        The delay margin, s.

    Returns
    -------
    float
        The axis's end, s (> 0).
    """
    from drake_coop.robot.pacing import percentile

    x = np.asarray(values_s, dtype=float)
    x = x[np.isfinite(x)]
    top = CLIP_HEADROOM * percentile(x, CLIP_PERCENTILE) if x.size else 0.0
    if margin_s is not None and math.isfinite(margin_s):
        top = max(top, 1.1 * margin_s)
    return top if top > 0 else 1e-3


def _outliers(ax, t, x, limit, label: str, axis: str = "y") -> int:
    """Mark the values above ``limit`` at the axes' edge; the count and the largest in the
    legend; returns their count."""
    beyond = x > limit
    count = int(beyond.sum())
    if count:
        text = f"{count} {label} beyond the axis (max {x.max():.3g} ms)"
        if axis == "y":
            ax.plot(t[beyond], np.full(count, limit * 0.98), "v", color="C3", ms=6, label=text)
        else:
            ax.axvline(limit * 0.995, color="C3", ls=":", label=text)
    return count


def plot_pacing(path: Path, record: PacingRecord, summary: dict) -> dict:
    """``pacing.png``: histograms of computation time and lateness, their time series and the
    status age, with the delay margin drawn. Each axis ends at :func:`clip_limit` (a high
    percentile, or the margin); the ticks beyond it are marked at the edge and counted.

    Parameters
    ----------
    path : Path
        The file.
    record : PacingRecord
        The figures.
    summary : dict
        :func:`pacing_summary`'s.

    Returns
    -------
    dict
        Per panel (``compute``, ``lateness``, ``series``, ``status_age``): ``limit_ms`` (the
        axis's end) and ``beyond`` (the ticks past it).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drake_coop.results.io import atomic_path
    from drake_coop.robot.pacing import percentile, summary_line

    a = record.arrays()
    ms = 1e3
    margin = summary["delay_margin_s"]
    shown = margin is not None and math.isfinite(margin)
    out = {}
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    for ax, key, name, label in (
            (axes[0, 0], "compute_s", "compute", "computation time per tick"),
            (axes[0, 1], "lateness_s", "lateness", "lateness of the command vs t_k")):
        x = a[key] * ms
        limit = clip_limit(a[key], margin) * ms
        ax.hist(np.minimum(x, limit), bins=60, range=(min(0.0, float(x.min(initial=0))), limit),
                color="C0")
        ax.set_yscale("log")
        ax.set_xlim(right=limit)
        ax.set_xlabel(f"{label} (ms)")
        ax.set_ylabel("ticks")
        ax.axvline(percentile(a[key], 99) * ms, color="C1", ls="--", label="99th percentile")
        if shown:
            ax.axvline(margin * ms, color="C3", label=f"delay margin {margin * ms:.3g} ms")
        out[name] = {"limit_ms": limit,
                     "beyond": _outliers(ax, a["t"], x, limit, "ticks (last bin)", axis="x")}
        ax.legend(fontsize=8)
    ax = axes[1, 0]
    both = np.concatenate([a["compute_s"], a["lateness_s"]])
    limit = clip_limit(both, margin) * ms
    ax.plot(a["t"], np.minimum(a["compute_s"] * ms, limit), lw=0.5, label="computation")
    ax.plot(a["t"], np.minimum(a["lateness_s"] * ms, limit), lw=0.5, label="lateness")
    if shown:
        ax.axhline(margin * ms, color="C3", label="delay margin")
    beyond = _outliers(ax, a["t"], np.maximum(a["compute_s"], a["lateness_s"]) * ms, limit,
                       "ticks")
    ax.set_ylim(0.0, limit)
    out["series"] = {"limit_ms": limit, "beyond": beyond}
    ax.set_xlabel("t (s)")
    ax.set_ylabel("ms")
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    x = a["status_age_s"] * ms
    limit = clip_limit(a["status_age_s"]) * ms
    ax.plot(a["t"], np.minimum(x, limit), lw=0.5, color="C2")
    out["status_age"] = {"limit_ms": limit, "beyond": _outliers(ax, a["t"], x, limit, "ticks")}
    ax.set_ylim(0.0, limit)
    if out["status_age"]["beyond"]:
        ax.legend(fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("age of the status used (ms)")
    fig.suptitle(summary_line(summary), fontsize=7, wrap=True)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
    return out
