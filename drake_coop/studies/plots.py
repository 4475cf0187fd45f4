"""Figures of a study, drawn from its ``study.json`` (PNG, on an Agg canvas).

* ``<name>_vs_<param>.png`` — for each grid parameter with several values: each plotted metric
  against it, the median (line) and min–max (band) over every other parameter and sample, ``ok``
  cases only; the values where cases diverged or failed are marked ✕ with their count. When another grid
  parameter takes text values (``velocity_source: [observer, measured]``), one curve per value.
* ``<name>_map.png`` — over the first two numeric grid parameters with several values: each
  metric's median as a coloured square, ✕ where every case diverged (the stability region's
  complement), a half-filled marker where some did; the study's ``guides`` as lines.
* ``<name>_hist.png`` — Monte Carlo: a histogram of each metric over the ``ok`` cases, with
  the fraction that diverged.

Axes are labelled in words with their units (:func:`metric_label`, :func:`param_label`), not
with the dotted paths of the study file: ``worst.force_error.rms`` reads "λ − λ_d, RMS, worst
robot [N]" (in mathtext), ``robots.*.gains.k_d`` reads "k_d, every robot [1/s]" (units
from the scenario's bounds table). Lengths and angles are drawn in the unit a reader reads (µm or mm, µrad or
mrad, mrad/s), chosen from the plotted values; the files keep SI values.

A study whose ``study.json`` is not at hand (the shipped studies keep only their
``results.csv``) is drawn by :func:`plot_results` from the ``results.csv`` and the study file
it ran: :func:`results_document` rebuilds the document ``study.json`` would hold (each row's
grid point and draw from the study file's expansion, checked against the row's own columns;
its status, message and summary columns from the row). A row a guard rewrote to ``failed``
after the run (``bench/guard_audit.py``) is then drawn ✕ like a case that failed at run time.
Each such figure names its source in its PNG text field ``Results``
(``<file name> sha256:<hex of its bytes>``), so a test can tell a figure drawn from an older
``results.csv``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure

from drake_coop.results.io import atomic_path
from drake_coop.studies.spec import file_stem

__all__ = ["SOURCE_KEY", "metric_label", "param_label", "plot_results", "plot_study",
           "results_document", "source_text"]

DPI = 110
#: The PNG text field that names the ``results.csv`` a figure was drawn from
#: (:func:`plot_results`).
SOURCE_KEY = "Results"
#: A case's statuses drawn as ✕: a run that diverged or failed its task (a failure guard).
_NOT_OK = ("diverged", "failed")

#: Error names of the summary columns, in words.
ERROR_NAMES = {
    # the Cartesian errors by their axis, not x-, y-, z-tilde: z is the observer's q - q-hat
    "x_tilde": r"$(x - x_d)_x$", "y_tilde": r"$(x - x_d)_y$", "z_tilde": r"$(x - x_d)_z$",
    "position_error": r"$|x - x_d|$ (worst axis)", "force_error": r"$\lambda - \lambda_d$",
    "estimate_error": r"$\lambda - \hat\lambda$", "aux_force_error": r"$\hat\lambda - \lambda_d$",
    "observation_error": r"$z = q - \hat q$ (worst joint)",
    "velocity_error": r"$\dot q - \hat{\dot q}$ (worst joint)",
}
#: SI unit of each error and the display units to choose from, smallest first.
_LENGTH = ("m", ((1e6, "µm"), (1e3, "mm"), (1.0, "m")))
_ANGLE = ("rad", ((1e6, "µrad"), (1e3, "mrad"), (1.0, "rad")))
_UNITS = {"force_error": ("N", ((1.0, "N"),)), "estimate_error": ("N", ((1.0, "N"),)),
          "aux_force_error": ("N", ((1.0, "N"),)), "velocity_error":
          ("rad/s", ((1e3, "mrad/s"), (1.0, "rad/s"))), "observation_error": _ANGLE,
          "x_tilde": _LENGTH, "y_tilde": _LENGTH, "z_tilde": _LENGTH, "position_error": _LENGTH}
#: Scenario fields with a display name and scale (factor, unit) other than their SI value.
_PARAMS = {"control_period": ("control period h", 1e3, "ms"),
           "plant.time_step": ("plant step", 1e3, "ms"),
           "robots.*.encoders.counts_per_rev": ("encoder counts per revolution", 1.0, ""),
           "robots.*.force_sensor.noise_std": ("F/T sensor noise σ, every robot", 1.0, "N")}


def _metric_parts(metric: str) -> tuple[str, str, str]:
    robot, error, stat = metric.split(".")
    return robot, error, stat


def _metric_unit(metric: str, values) -> tuple[float, str]:
    """(factor, unit) of a metric for display: the first unit in which its largest finite
    value is below 1000."""
    error = _metric_parts(metric)[1]
    _, units = _UNITS.get(error, _ANGLE if error[:1] == "z" and error[1:].isdigit() else
                          ("", ((1.0, ""),)))
    v = np.abs(np.asarray([x for x in values if np.isfinite(x)], dtype=float))
    peak = float(v.max()) if v.size else 0.0
    return next(((f, u) for f, u in units if peak * f < 1000), units[-1])


def metric_label(metric: str, unit: str) -> str:
    """``worst.force_error.rms`` → ``λ − λ_d, RMS, worst robot [N]``.

    Parameters
    ----------
    metric : str
        A summary column's name.
    unit : str
        Its unit.
    """
    robot, error, stat = _metric_parts(metric)
    name = ERROR_NAMES.get(error, f"z of joint {error[1:]}" if error[:1] == "z" else error)
    who = "worst robot" if robot == "worst" else robot
    text = f"{name}, {stat.upper() if stat == 'rms' else stat}, {who}"
    return f"{text} [{unit}]" if unit else text


def param_label(param: str) -> tuple[str, float]:
    """A grid parameter's axis label and the factor its values are drawn with:
    ``control_period`` → (``control period h [ms]``, 1000); ``robots.*.gains.k_d`` →
    (``k_d, every robot [1/s]``, 1) with the unit of the scenario's bounds table.

    Parameters
    ----------
    param : str
        A grid parameter's path.
    """
    if param in _PARAMS:
        name, factor, unit = _PARAMS[param]
        return (f"{name} [{unit}]" if unit else name), factor
    from drake_coop.scenario.validation import BOUNDS
    parts = param.split(".")
    pattern = ".".join("[]" if p == "*" or p.isdigit() else p for p in parts)
    pattern = pattern.replace(".[]", "[]")
    bound = BOUNDS.get(pattern) or BOUNDS.get(pattern + "[]")
    words = [p for p in parts if p not in ("*",) and not p.isdigit() and p != "robots"]
    who = ""
    if parts[:2] == ["robots", "*"]:
        who = ", every robot"
    elif len(parts) > 1 and parts[0] == "robots" and parts[1].isdigit():
        who = f", robot {int(parts[1]) + 1}"
    name = (words[-1] if words else "variant") + who
    unit = bound.unit if bound is not None and bound.unit else ""
    return (f"{name} [{unit}]" if unit else name), 1.0


def _numeric(values: list) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _label(value) -> str:
    """A grid value as text: a variant mapping as ``k=v k=v``."""
    if isinstance(value, dict):
        return " ".join(f"{k}={_label(v)}" for k, v in value.items())
    return str(value)


def _slug(path: str) -> str:
    return file_stem(path.replace("robots.*.", "").replace(".*", "").replace(".", "_"))


def _save(fig: Figure, path: Path, source: str | None = None) -> Path:
    """Write ``path`` (a file name made by :func:`file_stem`, directly in the study folder),
    with ``source`` in its text field :data:`SOURCE_KEY` when given."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI,
                    metadata={SOURCE_KEY: source} if source else None)
    return path


def _log_scale(values: np.ndarray) -> bool:
    values = values[np.isfinite(values)]
    return values.size > 1 and bool(np.all(values > 0)) and values.max() > 30 * values.min()


def _swept(doc: dict) -> list[str]:
    return [k for k, v in doc["grid"].items() if len({json.dumps(x) for x in v}) > 1]


def _value(case: dict, metric: str) -> float:
    v = case["summary"].get(metric) if case["status"] == "ok" else None
    return float(v) if v is not None else math.nan


def _category_labels(values: list) -> list[str]:
    """Tick labels of a categorical axis: a variant one ``key=value`` per line, other text
    wrapped at spaces to 20 characters (a number is never cut)."""
    import textwrap

    def text(v) -> str:
        if isinstance(v, dict):
            return "\n".join(f"{k}={_label(x)}" for k, x in v.items())
        return "\n".join(textwrap.wrap(_label(v), 20, break_long_words=False,
                                        break_on_hyphens=False)) or "''"
    return [text(v) for v in values]


def _figure_vs(doc: dict, param: str) -> Figure:
    """The metrics against one swept parameter: a numeric parameter on a numeric axis, one
    line per group with its min–max band; a categorical one (names, variants) with each value
    its own category, median markers and min–max bars, nothing drawn between categories, the
    labels on lines and, when they would not fit side by side, upright."""
    cases, metrics = doc["cases"], doc["metrics"]
    values = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][param]))
    xs_raw = [json.loads(v) for v in values]
    numeric = _numeric(xs_raw)
    xlabel, xfactor = param_label(param)
    xs = xfactor * np.array(xs_raw, dtype=float) if numeric else np.arange(len(values),
                                                                            dtype=float)
    split = next((k for k in _swept(doc) if k != param and not _numeric(doc["grid"][k])), None)
    groups = list(dict.fromkeys(json.dumps(c["params"][split]) for c in cases)) if split else [
        None]
    labels = [] if numeric else _category_labels(xs_raw)
    longest = max((len(line) for t in labels for line in t.split("\n")), default=0)
    # Turned upright when level labels would not fit side by side (7 pt: ~0.065 in a character).
    turned = not numeric and longest * 0.065 > 6.5 / max(1, len(labels))
    lines = max((t.count("\n") + 1 for t in labels), default=0)
    extra = 0.0 if numeric else (0.065 * longest if turned else 0.14 * lines)
    fig = Figure(figsize=(7.5, 2.6 * len(metrics) + extra), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(metrics), 1, sharex=True, squeeze=False)[:, 0]
    width = 0.6 / len(groups)               # categorical: the groups side by side in a slot
    for ax, metric in zip(axes, metrics):
        top = []
        factor, unit = _metric_unit(metric, [_value(c, metric) for c in cases])
        for g_index, group in enumerate(groups):
            members = [c for c in cases if split is None or json.dumps(c["params"][split]) ==
                       group]
            med, lo, hi, n_div = [], [], [], []
            for v in values:
                at = [c for c in members if json.dumps(c["params"][param]) == v]
                y = factor * np.array([_value(c, metric) for c in at])
                y = y[np.isfinite(y)]
                med.append(np.median(y) if y.size else math.nan)
                lo.append(y.min() if y.size else math.nan)
                hi.append(y.max() if y.size else math.nan)
                n_div.append(sum(c["status"] in _NOT_OK for c in at))
            label = "median" if group is None else _label(json.loads(group))
            if numeric:
                gx = xs
                line, = ax.plot(gx, med, "o-", ms=3, label=label)
                ax.fill_between(gx, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
            else:
                gx = xs + (g_index - (len(groups) - 1) / 2) * width
                line, = ax.plot(gx, med, "o", ls="none", ms=5, label=label)
                ax.vlines(gx, lo, hi, color=line.get_color(), lw=2, alpha=0.4)
            top += [v for v in hi if np.isfinite(v)]
            for x, n in zip(gx, n_div):
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
        ax.set_ylabel(metric_label(metric, unit), fontsize=8)
        ax.grid(True, alpha=0.3, axis="y" if not numeric else "both")
        if split is not None or len(groups) > 1:
            ax.legend(fontsize=7)
    if not numeric:
        axes[-1].set_xticks(xs, labels, fontsize=7, rotation=90 if turned else 0,
                            ha="center", va="top")
        axes[-1].set_xlim(-0.5, len(xs) - 0.5)
    elif _log_scale(xs):
        axes[-1].set_xscale("log")
        axes[-1].set_xlim(xs.min() / 1.2, xs.max() * 1.2)
    else:
        pad = 0.05 * (xs.max() - xs.min()) or 0.5
        axes[-1].set_xlim(xs.min() - pad, xs.max() + pad)
    axes[-1].set_xlabel(xlabel)
    what = "median (line) and min–max (band)" if numeric else "median (dot) and min–max (bar)"
    fig.suptitle(f"{doc['name']}: {what} over the other parameters\n"
                 f"(phase {doc['phase']}; ✕ n: n cases diverged or failed)", fontsize=9)
    return fig


def _plot_vs(doc: dict, param: str, out: Path) -> Path:
    return _save(_figure_vs(doc, param), out / f"{file_stem(doc['name'])}_vs_{_slug(param)}.png",
                 doc.get("source"))


def _plot_map(doc: dict, px: str, py: str, out: Path) -> Path:
    cases, metrics = doc["cases"], doc["metrics"]
    xs = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][px]))
    ys = list(dict.fromkeys(json.dumps(v) for v in doc["grid"][py]))
    fig = Figure(figsize=(6.2 * len(metrics), 5.8), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    xv = np.array([json.loads(v) for v in xs], dtype=float)
    yv = np.array([json.loads(v) for v in ys], dtype=float)
    (xlabel, fx), (ylabel, fy) = param_label(px), param_label(py)
    for ax, metric in zip(axes, metrics):
        factor, unit = _metric_unit(metric, [_value(c, metric) for c in cases])
        cx, cy, cz, dx, dy, px_, py_ = [], [], [], [], [], [], []
        for x in xs:
            for y in ys:
                at = [c for c in cases if json.dumps(c["params"][px]) == x
                      and json.dumps(c["params"][py]) == y]
                z = factor * np.array([_value(c, metric) for c in at])
                z = z[np.isfinite(z)]
                n_div = sum(c["status"] in _NOT_OK for c in at)
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
            fig.colorbar(sc, ax=ax, label=metric_label(metric, unit))
        if dx:
            ax.scatter(dx, dy, s=90, marker="x", color="crimson", label="diverged or failed")
        if px_:
            ax.scatter(px_, py_, s=120, marker="o", facecolors="none", edgecolors="crimson",
                       label="some diverged or failed")
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
        ax.set_xlabel(xlabel if fx == 1.0 else px)
        ax.set_ylabel(ylabel if fy == 1.0 else py)
        ax.set_title(metric_label(metric, unit), fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    fig.suptitle(f"{doc['name']}: median over other parameters (phase {doc['phase']})",
                 fontsize=9)
    return _save(fig, out / f"{file_stem(doc['name'])}_map.png", doc.get("source"))


def _figure_hist(doc: dict) -> Figure:
    """The Monte Carlo histograms of the ``ok`` cases, the count that diverged or failed in
    the title."""
    cases, metrics = doc["cases"], doc["metrics"]
    n_div = sum(c["status"] in _NOT_OK for c in cases)
    n_done = sum(c["status"] in ("ok", *_NOT_OK, "error") for c in cases)
    fig = Figure(figsize=(4.2 * len(metrics), 3.4), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    for ax, metric in zip(axes, metrics):
        factor, unit = _metric_unit(metric, [_value(c, metric) for c in cases])
        y = factor * np.array([_value(c, metric) for c in cases])
        y = y[np.isfinite(y)]
        if y.size:
            ax.hist(y, bins=min(30, max(5, y.size // 3)), color="C0", alpha=0.8)
            ax.axvline(np.median(y), color="k", lw=1, ls="--",
                       label=f"median {np.median(y):.3g}")
            ax.legend(fontsize=7)
        ax.set_xlabel(metric_label(metric, unit), fontsize=8)
        ax.set_ylabel("cases")
    fig.suptitle(f"{doc['name']}: {n_done} cases, {n_div} diverged or failed "
                 f"({100.0 * n_div / max(1, n_done):.0f} %), phase {doc['phase']}", fontsize=9)
    return fig


def _plot_hist(doc: dict, out: Path) -> Path:
    return _save(_figure_hist(doc), out / f"{file_stem(doc['name'])}_hist.png",
                 doc.get("source"))


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

    Parameters
    ----------
    out_dir : str or Path
        The study's folder.

    Returns
    -------
    list of Path
        The files written.

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
    return _draw(doc, path, out)


def _draw(doc: dict, path: Path, out: Path) -> list[Path]:
    """Every figure of the checked document ``doc`` (read from ``path``) into ``out``."""
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


#: Columns of ``results.csv`` around its parameters and summary (the store's layout:
#: ``index, hash, <parameters>, status, t_reached, wall_time_s, <summary>, message``).
_FIXED_COLUMNS = ("index", "hash", "status", "t_reached", "wall_time_s", "message")


def source_text(path: str | Path) -> str:
    """The source a figure drawn from ``path`` names: ``<file name> sha256:<hex>`` of its bytes.

    Parameters
    ----------
    path : str or Path
        A ``results.csv``.

    Returns
    -------
    str
        What :func:`plot_results` writes in the figure's :data:`SOURCE_KEY` field.
    """
    path = Path(path)
    return f"{path.name} sha256:{hashlib.sha256(path.read_bytes()).hexdigest()}"


def results_document(study_file: str | Path, results_csv: str | Path) -> dict:
    """The document ``study.json`` would hold, rebuilt from a study's ``results.csv`` and the
    study file it ran.

    The cases are the study file's expansion, sized as the run was: as many Monte Carlo
    draws as the ``sample`` column holds, as many cases as the file has rows (a
    ``--draws``/``--cases`` run). Each row must be its case: the same ``index``, and each of
    its parameter columns the text the store writes for the case's value; the row gives the
    case's ``status``, ``message`` and summary columns (an empty cell: no value).

    Parameters
    ----------
    study_file : str or Path
        The study's YAML file (its name, grid, Monte Carlo block, phase, metrics and guides).
    results_csv : str or Path
        The study's ``results.csv`` (a shipped copy may have another name).

    Returns
    -------
    dict
        The study document (:func:`plot_study`'s ``study.json``), with ``source``:
        :func:`source_text` of ``results_csv``.

    Raises
    ------
    ValueError
        One line naming the file and the field: a study file the loader refuses, a
        ``results.csv`` without the store's columns, more rows than the study has cases, a row
        that is not its case (the study file changed since the run), a summary cell that is
        not a number.
    OSError
        If a file cannot be read.
    """
    from drake_coop.studies.expand import expand
    from drake_coop.studies.size import apply_size
    from drake_coop.studies.spec import load_study
    from drake_coop.studies.store import _cell

    results_csv = Path(results_csv)
    with open(results_csv, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header, rows = list(reader.fieldnames or []), list(reader)
    missing = [c for c in _FIXED_COLUMNS if c not in header]
    if missing or not rows:
        raise ValueError(f"{results_csv}: not a study's results.csv (needs rows and the columns "
                         f"{', '.join(_FIXED_COLUMNS)}; missing {', '.join(missing) or 'rows'})")
    study = load_study(study_file)
    size = {}
    if study.monte_carlo is not None and "sample" in header:
        try:
            size["draws"] = 1 + max(int(r["sample"]) for r in rows)
        except ValueError:
            raise ValueError(f"{results_csv}: column sample must hold integers >= 0") from None
    study, _ = apply_size(study, size)
    cases = expand(study)
    if len(rows) > len(cases):
        raise ValueError(f"{results_csv}: {len(rows)} rows, but {study_file} has {len(cases)} "
                         "cases at this size")
    summary_columns = header[header.index("wall_time_s") + 1:header.index("message")]
    out = []
    for case, row in zip(cases, rows):
        given = {"index": case.index, **case.values}
        wrong = next((k for k, v in given.items() if row.get(k) != _cell(v)), None)
        if wrong is not None:
            raise ValueError(f"{results_csv} row {row['index']!r}: {wrong} is "
                             f"{row.get(wrong)!r}, the study file {study_file} gives "
                             f"{_cell(given[wrong])!r} (the study file changed since the run)")
        try:
            summary = {k: float(row[k]) for k in summary_columns if row[k] not in ("", None)}
        except ValueError:
            raise ValueError(f"{results_csv} row {row['index']!r}: a summary column holds a "
                             "value that is not a number") from None
        out.append({"index": case.index, "hash": row["hash"], "params": case.params,
                    "values": case.values, "status": row["status"],
                    "message": row["message"], "summary": summary})
    return {"name": study.name, "description": study.description, "t_end": study.t_end,
            "phase": study.phase, "grid": study.grid,
            "monte_carlo": asdict(study.monte_carlo) if study.monte_carlo else None,
            "metrics": study.metrics, "guides": [asdict(g) for g in study.guides],
            "cases": out, "source": source_text(results_csv)}


def plot_results(study_file: str | Path, results_csv: str | Path,
                 out_dir: str | Path) -> list[Path]:
    """Draw every figure of a study from its ``results.csv`` and study file (no ``study.json``).

    The figures are those :func:`plot_study` draws, named the same, each naming its source
    (:func:`source_text`) in its text field :data:`SOURCE_KEY`.

    Parameters
    ----------
    study_file : str or Path
        The study's YAML file.
    results_csv : str or Path
        Its ``results.csv`` (:func:`results_document`).
    out_dir : str or Path
        The existing folder the figures are written into.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        As :func:`results_document` (one line).
    OSError
        If a file cannot be read or a figure written.
    """
    doc = results_document(study_file, results_csv)
    _check_doc(doc, Path(results_csv))
    return _draw(doc, Path(results_csv), Path(out_dir))
