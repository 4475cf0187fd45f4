"""Figures of a study, drawn from its ``study.json`` (PNG, on an Agg canvas).

* ``<name>_vs_<param>.png`` — for each grid parameter with several values: each plotted metric
  against it, the median (line) and min–max (band) over every other parameter and sample, ``ok``
  cases only; the values where cases diverged are marked ✕ with their count. When another grid
  parameter takes text values (``velocity_source: [observer, measured]``), one curve per value.
* ``<name>_map.png`` — over the first two numeric grid parameters with several values: each
  metric's median as a coloured square, ✕ where every case diverged (the stability region's
  complement), a half-filled marker where some did; the study's ``guides`` as lines.
* ``<name>_hist.png`` — Monte Carlo: a histogram of each metric over the ``ok`` cases, with
  the fraction that diverged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure

from drake_coop.results.io import atomic_path
from drake_coop.studies.spec import file_stem

__all__ = ["plot_study"]

DPI = 110


def _numeric(values: list) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _label(value) -> str:
    """A grid value as text: a variant mapping as ``k=v k=v``."""
    if isinstance(value, dict):
        return " ".join(f"{k}={_label(v)}" for k, v in value.items())
    return str(value)


def _slug(path: str) -> str:
    return file_stem(path.replace("robots.*.", "").replace(".*", "").replace(".", "_"))


def _save(fig: Figure, path: Path) -> Path:
    """Write ``path`` (a file name made by :func:`file_stem`, directly in the study folder)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI)
    return path


def _log_scale(values: np.ndarray) -> bool:
    values = values[np.isfinite(values)]
    return values.size > 1 and bool(np.all(values > 0)) and values.max() > 30 * values.min()


def _swept(doc: dict) -> list[str]:
    return [k for k, v in doc["grid"].items() if len({json.dumps(x) for x in v}) > 1]


def _value(case: dict, metric: str) -> float:
    v = case["summary"].get(metric) if case["status"] == "ok" else None
    return float(v) if v is not None else math.nan


def _plot_vs(doc: dict, param: str, out: Path) -> Path:
    cases, metrics = doc["cases"], doc["metrics"]
    values = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][param]))
    xs_raw = [json.loads(v) for v in values]
    numeric = _numeric(xs_raw)
    xs = np.array(xs_raw, dtype=float) if numeric else np.arange(len(values), dtype=float)
    split = next((k for k in _swept(doc) if k != param and not _numeric(doc["grid"][k])), None)
    groups = list(dict.fromkeys(json.dumps(c["params"][split]) for c in cases)) if split else [
        None]
    fig = Figure(figsize=(7.5, 2.6 * len(metrics)), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(metrics), 1, sharex=True, squeeze=False)[:, 0]
    for ax, metric in zip(axes, metrics):
        top = []
        for g_index, group in enumerate(groups):
            members = [c for c in cases if split is None or json.dumps(c["params"][split]) ==
                       group]
            med, lo, hi, n_div = [], [], [], []
            for v in values:
                at = [c for c in members if json.dumps(c["params"][param]) == v]
                y = np.array([_value(c, metric) for c in at])
                y = y[np.isfinite(y)]
                med.append(np.median(y) if y.size else math.nan)
                lo.append(y.min() if y.size else math.nan)
                hi.append(y.max() if y.size else math.nan)
                n_div.append(sum(c["status"] == "diverged" for c in at))
            label = "median" if group is None else _label(json.loads(group))
            line, = ax.plot(xs, med, "o-", ms=3, label=label)
            ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
            top += [v for v in hi if np.isfinite(v)]
            for x, n in zip(xs, n_div):
                if n:
                    level = 0.96 - 0.12 * g_index      # one row of marks per curve
                    ax.plot([x], [level], "x", color=line.get_color(), ms=7,
                            transform=ax.get_xaxis_transform())
                    ax.annotate(f"{n}", (x, level - 0.03), xycoords=("data", "axes fraction"),
                                ha="center", va="top", color=line.get_color(), fontsize=7,
                                annotation_clip=False)
        finite = np.array(top)
        if _log_scale(finite):
            ax.set_yscale("log")
        ax.set_ylabel(metric, fontsize=8)
        ax.grid(True, alpha=0.3)
        if split is not None or len(groups) > 1:
            ax.legend(fontsize=7)
    if not numeric:
        axes[-1].set_xticks(xs, [_label(x) for x in xs_raw], fontsize=7)
    if numeric and _log_scale(xs):
        axes[-1].set_xscale("log")
        axes[-1].set_xlim(xs.min() / 1.2, xs.max() * 1.2)
    else:
        pad = 0.05 * (xs.max() - xs.min()) or 0.5
        axes[-1].set_xlim(xs.min() - pad, xs.max() + pad)
    axes[-1].set_xlabel(param)
    fig.suptitle(f"{doc['name']}: median and min–max over the other parameters "
                 f"(phase {doc['phase']}; ✕ n: n cases diverged)", fontsize=9)
    return _save(fig, out / f"{file_stem(doc['name'])}_vs_{_slug(param)}.png")


def _plot_map(doc: dict, px: str, py: str, out: Path) -> Path:
    cases, metrics = doc["cases"], doc["metrics"]
    xs = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][px]))
    ys = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][py]))
    fig = Figure(figsize=(6.2 * len(metrics), 5.8), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    xv = np.array([json.loads(v) for v in xs], dtype=float)
    yv = np.array([json.loads(v) for v in ys], dtype=float)
    for ax, metric in zip(axes, metrics):
        cx, cy, cz, dx, dy, px_, py_ = [], [], [], [], [], [], []
        for x in xs:
            for y in ys:
                at = [c for c in cases if json.dumps(c["params"][px]) == x
                      and json.dumps(c["params"][py]) == y]
                z = np.array([_value(c, metric) for c in at])
                z = z[np.isfinite(z)]
                n_div = sum(c["status"] == "diverged" for c in at)
                if z.size:
                    cx.append(json.loads(x)); cy.append(json.loads(y)); cz.append(np.median(z))
                if at and n_div == len(at):
                    dx.append(json.loads(x)); dy.append(json.loads(y))
                elif n_div:
                    px_.append(json.loads(x)); py_.append(json.loads(y))
        cz_arr = np.array(cz)
        norm = LogNorm() if _log_scale(cz_arr) else Normalize()
        if cz:
            sc = ax.scatter(cx, cy, c=cz, s=260, marker="s", norm=norm, cmap="viridis")
            fig.colorbar(sc, ax=ax, label=metric)
        if dx:
            ax.scatter(dx, dy, s=90, marker="x", color="crimson", label="diverged")
        if px_:
            ax.scatter(px_, py_, s=120, marker="o", facecolors="none", edgecolors="crimson",
                       label="some diverged")
        if _log_scale(xv):
            ax.set_xscale("log")
        if _log_scale(yv):
            ax.set_yscale("log")
        xline = np.geomspace(xv.min(), xv.max(), 200) if _log_scale(xv) else np.linspace(
            xv.min(), xv.max(), 200)
        ylim = (yv.min() / 1.3, yv.max() * 1.3) if _log_scale(yv) else None
        for g in doc.get("guides", []):
            ax.plot(xline, g["slope"] * xline + g["intercept"], "--", lw=1, label=g["label"])
        if ylim:
            ax.set_ylim(*ylim)
        ax.set_xlabel(px)
        ax.set_ylabel(py)
        ax.set_title(metric, fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    fig.suptitle(f"{doc['name']}: median over other parameters (phase {doc['phase']})",
                 fontsize=9)
    return _save(fig, out / f"{file_stem(doc['name'])}_map.png")


def _plot_hist(doc: dict, out: Path) -> Path:
    cases, metrics = doc["cases"], doc["metrics"]
    n_div = sum(c["status"] == "diverged" for c in cases)
    n_done = sum(c["status"] in ("ok", "diverged", "error") for c in cases)
    fig = Figure(figsize=(4.2 * len(metrics), 3.4), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    for ax, metric in zip(axes, metrics):
        y = np.array([_value(c, metric) for c in cases])
        y = y[np.isfinite(y)]
        if y.size:
            ax.hist(y, bins=min(30, max(5, y.size // 3)), color="C0", alpha=0.8)
            ax.axvline(np.median(y), color="k", lw=1, ls="--",
                       label=f"median {np.median(y):.3g}")
            ax.legend(fontsize=7)
        ax.set_xlabel(metric, fontsize=8)
        ax.set_ylabel("cases")
    fig.suptitle(f"{doc['name']}: {n_done} cases, {n_div} diverged "
                 f"({100.0 * n_div / max(1, n_done):.0f} %), phase {doc['phase']}", fontsize=9)
    return _save(fig, out / f"{file_stem(doc['name'])}_hist.png")


#: Largest ``study.json`` read (bytes) and cases plotted.
MAX_DOC_BYTES = 256_000_000
MAX_PLOT_CASES = 1_000_000


def _check_doc(doc, path: Path) -> None:
    """Raise ValueError (one line) unless ``doc`` has the structure the figures read."""
    def bad(what: str):
        raise ValueError(f"{path} is damaged: {what}; rerun the study to rewrite it")

    if not isinstance(doc, dict):
        bad("not a JSON object")
    if not isinstance(doc.get("name"), str):
        bad("'name' must be a text")
    grid, cases, metrics = doc.get("grid"), doc.get("cases"), doc.get("metrics")
    if not isinstance(grid, dict) or not all(isinstance(v, list) and v for v in grid.values()):
        bad("'grid' must map paths to lists of values")
    if not (isinstance(metrics, list) and 0 < len(metrics) <= 20
            and all(isinstance(m, str) for m in metrics)):
        bad("'metrics' must be a list of 1 to 20 column names")
    if not isinstance(cases, list) or len(cases) > MAX_PLOT_CASES:
        bad(f"'cases' must be a list of at most {MAX_PLOT_CASES} cases")
    for c in cases:
        if not (isinstance(c, dict) and isinstance(c.get("params"), dict)
                and isinstance(c.get("status"), str) and isinstance(c.get("summary"), dict)
                and all(k in c["params"] for k in grid)):
            bad("a case needs 'params' (every grid path), 'status' and 'summary'")
    guides = doc.get("guides", [])
    if not isinstance(guides, list) or not all(
            isinstance(g, dict) and isinstance(g.get("slope"), (int, float))
            and isinstance(g.get("intercept", 0.0), (int, float)) for g in guides):
        bad("'guides' must be a list of {label, slope, intercept}")


def plot_study(out_dir: str | Path) -> list[Path]:
    """Draw every figure of the study in ``out_dir`` (from its ``study.json``).

    The figures are written only into ``out_dir``, named from :func:`file_stem` of the
    study's name (whatever ``study.json`` holds).

    Raises
    ------
    FileNotFoundError
        If ``out_dir/study.json`` does not exist.
    ValueError
        If ``study.json`` is too large, not UTF-8 JSON or damaged (one-line message).
    OSError
        If a figure cannot be written (read-only folder, full disk).
    """
    out = Path(out_dir)
    path = out / "study.json"
    if not path.is_file() or path.is_symlink():
        raise FileNotFoundError(f"no study.json in {out} (run `drake-coop study` first)")
    if path.stat().st_size > MAX_DOC_BYTES:
        raise ValueError(f"{path} is larger than {MAX_DOC_BYTES} bytes")
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ValueError(f"{path} is not valid JSON ({' '.join(str(exc).split())[:100]}); "
                         "rerun the study to rewrite it") from None
    _check_doc(doc, path)
    written = []
    try:
        swept = _swept(doc)
        for param in swept:
            written.append(_plot_vs(doc, param, out))
        numeric = [k for k in swept if _numeric(doc["grid"][k])]
        if len(numeric) >= 2:
            written.append(_plot_map(doc, numeric[0], numeric[1], out))
        if doc.get("monte_carlo"):
            written.append(_plot_hist(doc, out))
    except (KeyError, TypeError, IndexError, ValueError) as exc:
        raise ValueError(f"{path} is damaged ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:100]}); rerun the study to rewrite "
                         "it") from None
    return written
