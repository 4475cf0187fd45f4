"""``stability.csv`` and the heat maps of ρ(Φ) with the ρ = 1 contour, with simulated outcomes.

One row per grid point and operating point: the swept values, then
:data:`~drake_coop.stability.grid.COLUMNS`. Maps: for two numeric swept paths, one heat map of
``log10 ρ`` per operating point (and per value of any other swept path) with the contour
``ρ = 1``; for one numeric path, ρ against it. An optional study ``results.csv`` (same swept
paths) is overlaid: its simulated outcome per point, ``ok`` (circle) or ``diverged`` (cross).
Every file is written to a temporary name and renamed.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_write_bytes
from drake_coop.stability.grid import COLUMNS

__all__ = ["OUTPUT_NAMES", "outcome_key", "plot_maps", "read_outcomes", "write_csv"]

#: What ``drake-coop stability`` writes into its folder (prefixes).
OUTPUT_NAMES = ("stability.csv", "stability_")


def _cell(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def write_csv(path: Path, swept: list[str], rows: list[dict]) -> None:
    """``stability.csv``: ``swept… , COLUMNS…`` (rows as given).

    Parameters
    ----------
    path : Path
        The file.
    swept : list of str
        The swept paths (the first columns).
    rows : list of dict
        The rows.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(swept + COLUMNS)
    for r in rows:
        w.writerow([_cell(r.get(k, "")) for k in swept + COLUMNS])
    atomic_write_bytes(Path(path), buf.getvalue().encode())


def _num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def read_outcomes(path: str | Path, swept: list[str]) -> dict[tuple, str]:
    """``values of the swept paths (as text) -> status`` from a study's ``results.csv``.

    The study's swept columns must include ours; extra ones (fixed there) are ignored.

    Parameters
    ----------
    path : str or Path
        The study's ``results.csv``.
    swept : list of str
        The swept paths.

    Returns
    -------
    dict of tuple to str
        Swept values → the run's status.
    """
    out = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if not all(k in r for k in swept):
                raise ValueError(f"{path}: the study results lack the columns "
                                 f"{', '.join(k for k in swept if k not in r)}")
            out[outcome_key(r, swept)] = r["status"]
    return out


def outcome_key(values, swept: list[str]) -> tuple[str, ...]:
    """The key of :func:`read_outcomes` for a grid point's ``values`` (a mapping of each swept
    path to its value: a study's row or a stability case's parameters).

    Parameters
    ----------
    values : Mapping
        Each swept path's value.
    swept : list of str
        The swept paths.
    """
    return tuple(_key(values[p]) for p in swept)


def _key(v) -> str:
    """A swept value as text for matching: numbers to 12 digits; a study's per-joint list
    (``"30.0 30.0 30.0"``: a ``*`` path set every joint of a list to one grid value) as that
    one value when all its entries are equal."""
    x = _num(v)
    if x is not None:
        return f"{x:.12g}"
    parts = [_num(p) for p in str(v).split()]
    if parts and all(p is not None for p in parts) and len(set(parts)) == 1:
        return f"{parts[0]:.12g}"
    return str(v)


def _rho_axis(ax, rho: list[float]) -> None:
    """ρ on a linear axis when it spans less than a factor 3 (a log axis would show one or
    two ticks), else on a log axis with ticks at 1, 2 and 5 per decade written as plain
    numbers (no minor labels)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    finite = [v for v in rho if np.isfinite(v) and v > 0]
    if not finite or max(finite) < 3 * min(finite):
        return
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def plot_maps(out: Path, swept: list[str], rows: list[dict],
              outcomes: dict[tuple, str] | None = None) -> list[Path]:
    """Heat maps (two numeric paths) or curves (one) of ρ; returns the files written. Axes
    are labelled with their unit (:func:`drake_coop.studies.plots.param_label`: a period in ms).

    Parameters
    ----------
    out : Path
        The output folder.
    swept : list of str
        The swept paths.
    rows : list of dict
        The rows.
    outcomes : dict of tuple to str or None
        A study's outcomes to mark on the maps.

    Returns
    -------
    list of Path
        The files written.
    """
    from drake_coop.studies.plots import param_label

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    numeric = [p for p in swept if all(_num(r.get(p)) is not None for r in rows)]
    others = [p for p in swept if p not in numeric]
    written = []
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["point"],) + tuple(str(r.get(p)) for p in others), []).append(r)
    for key, group in groups.items():
        label = ", ".join([f"point={key[0]}"] + [f"{p}={v}" for p, v in zip(others, key[1:])])
        slug = "_".join(str(k).replace(".", "p").replace("*", "all") for k in key)
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        if len(numeric) >= 2:
            px, py = numeric[-2], numeric[-1]
            xs = sorted({_num(r[px]) for r in group})
            ys = sorted({_num(r[py]) for r in group})
            Z = np.full((len(ys), len(xs)), np.nan)
            for r in group:
                rho = _num(r.get("rho"))
                if rho is not None and rho > 0:
                    Z[ys.index(_num(r[py])), xs.index(_num(r[px]))] = math.log10(rho)
            lim = max(0.3, float(np.nanmax(np.abs(Z)))) if np.any(np.isfinite(Z)) else 1.0
            X, Y = np.meshgrid(np.arange(len(xs)), np.arange(len(ys)))
            mesh = ax.pcolormesh(X, Y, Z, cmap="RdBu_r", vmin=-lim, vmax=lim, shading="nearest")
            fig.colorbar(mesh, ax=ax, label="log10 ρ(Φ)")
            if np.sum(np.isfinite(Z)) >= 4 and np.nanmin(Z) < 0 < np.nanmax(Z):
                ax.contour(X, Y, np.nan_to_num(Z, nan=np.nanmax(Z)), levels=[0.0],
                           colors="k", linewidths=2)
            for r in group:
                i, j = xs.index(_num(r[px])), ys.index(_num(r[py]))
                ax.text(i, j, f"{_num(r.get('rho')) or float('nan'):.2f}", ha="center",
                        va="top", fontsize=7)
                if outcomes is not None:
                    status = outcomes.get(outcome_key(r, swept))
                    if status is not None:
                        ax.plot(i, j + 0.22, "x" if status != "ok" else "o", ms=7,
                                mfc="none", color="k")
            (xlabel, fx), (ylabel, fy) = param_label(px), param_label(py)
            ax.set_xticks(range(len(xs)), [f"{fx * v:g}" for v in xs])
            ax.set_yticks(range(len(ys)), [f"{fy * v:g}" for v in ys])
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.set_title(f"ρ(Φ), black line ρ = 1; {label}" +
                         ("\nsimulated: o ok, x diverged" if outcomes else ""), fontsize=9)
        elif len(numeric) == 1:
            px = numeric[0]
            xlabel, factor = param_label(px)
            pts = sorted((factor * _num(r[px]), _num(r.get("rho")) or math.nan) for r in group)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label="ρ(Φ)")
            ax.axhline(1.0, color="k", lw=1)
            if outcomes is not None:
                for r in group:
                    status = outcomes.get(outcome_key(r, swept))
                    if status is not None:
                        ax.plot(factor * _num(r[px]), _num(r.get("rho")) or math.nan,
                                "x" if status != "ok" else "o", ms=10, mfc="none", color="k")
            _rho_axis(ax, [p[1] for p in pts])
            ax.set_xlabel(xlabel)
            ax.set_ylabel("spectral radius ρ(Φ)")
            ax.grid(True, which="major", alpha=0.3)
            ax.set_title(f"{label}" + ("; simulated: o ok, x diverged" if outcomes else ""),
                         fontsize=9)
        else:
            plt.close(fig)
            continue
        buf = io.BytesIO()
        fig.tight_layout()
        fig.savefig(buf, format="png", dpi=90)
        plt.close(fig)
        path = out / f"stability_{slug}.png"
        atomic_write_bytes(path, buf.getvalue())
        written.append(path)
    return written
