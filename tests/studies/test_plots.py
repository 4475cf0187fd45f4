"""A study figure against a categorical parameter (names, variants) draws categories: no line
or band joins two categories, and no tick label overlaps another. A shipped study's figures,
redrawn from its ``results.csv`` and study file, mark ✕ every row that diverged or failed
(counted in the figure's artists against the CSV), and a ``results.csv`` that is not its study
file's is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from drake_coop.studies.plots import _figure_vs

TIMING = [{"computation_delay": d} for d in (0.0, 0.002, 0.004, 0.006, 0.009)] + [
    {"jitter": "exponential", "jitter_scale": 0.0011, "seed": 1}] + [
    {"jitter": "uniform", "jitter_scale": s, "seed": 1} for s in (0.003, 0.006, 0.009)]


def _doc(grid: dict) -> dict:
    import itertools
    import json

    keys = list(grid)
    cases = []
    for i, combo in enumerate(itertools.product(*grid.values())):
        params = dict(zip(keys, combo))
        cases.append({"params": params, "status": "diverged" if i == 7 else "ok",
                      "summary": {"worst.force_error.rms": 0.04 + 0.01 * (i % 5),
                                  "worst.position_error.max": 2e-5 * (1 + i % 3)}})
    assert json.dumps(cases)
    return {"name": "timing", "phase": "circle", "grid": grid, "cases": cases,
            "metrics": ["worst.position_error.max", "worst.force_error.rms"]}


def _joins_categories(fig) -> list[str]:
    found = []
    for ax in fig.axes:
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata(), dtype=float)
            if np.isfinite(x).sum() > 1 and line.get_linestyle() not in ("None", "none", ""):
                found.append(f"line {line.get_label()}")
        found += [f"band {c}" for c in ax.collections if isinstance(c, PolyCollection)]
    return found


def _overlaps(fig) -> list[tuple[str, str]]:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = [t for t in fig.axes[-1].get_xticklabels() if t.get_text()]
    boxes = [t.get_window_extent(renderer) for t in labels]
    return [(labels[i].get_text(), labels[j].get_text())
            for i in range(len(boxes)) for j in range(i + 1, len(boxes))
            if boxes[i].overlaps(boxes[j])]


def test_categorical_parameter_is_drawn_as_categories_with_readable_labels():
    fig = _figure_vs(_doc({"robots.*.timing": TIMING}), "robots.*.timing")
    assert _joins_categories(fig) == []
    assert _overlaps(fig) == []
    ticks = [t.get_text() for t in fig.axes[-1].get_xticklabels()]
    assert len(ticks) == 9 and "computation_delay=0.002" in ticks[1].replace("\n", "")


def test_categories_split_by_a_second_categorical_parameter_stay_apart():
    doc = _doc({"robots.*.timing": TIMING[:4], "robots.*.force_source": ["observer", "sensor"]})
    fig = _figure_vs(doc, "robots.*.timing")
    assert _joins_categories(fig) == []
    xs = [tuple(line.get_xdata()) for line in fig.axes[0].get_lines() if len(line.get_xdata()) == 4]
    assert len(xs) == 2 and all(a != b for a, b in zip(*xs))       # side by side in each slot


def test_a_numeric_parameter_keeps_its_line_and_band():
    doc = _doc({"control_period": [0.003, 0.006, 0.009, 0.012]})
    fig = _figure_vs(doc, "control_period")
    assert _joins_categories(fig)                   # a numeric axis is a line, on purpose


# --- the shipped studies' figures, redrawn from their results.csv and study file -------------

ROOT = Path(__file__).resolve().parents[2]
NOT_OK = ("diverged", "failed")


def _rows(name: str) -> list[dict]:
    import csv

    with open(ROOT / "docs/figures/studies" / f"{name}_results.csv", newline="") as f:
        return list(csv.DictReader(f))


def _shipped(name: str) -> dict:
    from drake_coop.studies.plots import results_document

    return results_document(ROOT / "studies" / f"{name}.yaml",
                            ROOT / "docs/figures/studies" / f"{name}_results.csv")


def _marks(ax) -> dict[float, int]:
    """x → the count written under the ✕ marks at x (the axes' ``x`` markers, each with its
    count as the text just below it)."""
    marks = [line for line in ax.get_lines() if line.get_marker() == "x"]
    counts: dict[float, int] = {}
    for line in marks:
        (x,), (level,) = line.get_xdata(), line.get_ydata()
        text = next(t for t in ax.texts if t.xy == (x, level - 0.03))
        counts[float(x)] = counts.get(float(x), 0) + int(text.get_text())
    return counts


def test_the_redraw_of_a_shipped_study_marks_every_row_that_diverged_or_failed():
    """velocity_estimation's figures drawn from its shipped results.csv: over each metric's
    axes, the ✕ counts at each encoder resolution add up to the rows there that diverged or
    failed, the rows a guard rewrote ``failed`` after the run included (counted from the CSV
    itself, not from the document the figure reads)."""
    rows = _rows("velocity_estimation")
    rewritten = [r for r in rows if r["status"] == "failed"]
    assert len(rewritten) == 6                    # the rows bench.guard_audit rewrote
    want: dict[float, int] = {}
    for r in rows:
        x = float(r["robots.*.encoders.counts_per_rev"])
        want[x] = want.get(x, 0) + (r["status"] in NOT_OK)
    want = {x: n for x, n in want.items() if n}
    doc = _shipped("velocity_estimation")
    fig = _figure_vs(doc, "robots.*.encoders.counts_per_rev")
    assert len(fig.axes) == len(doc["metrics"]) == 3
    for ax in fig.axes:
        assert _marks(ax) == want
    # One ✕ per curve and resolution with such a row: the source (observer, measured, ...).
    sources = {(r["robots.*"], r["robots.*.encoders.counts_per_rev"]) for r in rows
               if r["status"] in NOT_OK}
    assert sum(line.get_marker() == "x" for line in fig.axes[0].get_lines()) == len(sources)
    # Against the categorical axis (the velocity source): the same rows, per source.
    fig = _figure_vs(doc, "robots.*")
    names = list(dict.fromkeys(r["robots.*"] for r in rows))
    per_source = {float(k): sum(r["status"] in NOT_OK for r in rows if r["robots.*"] == name)
                  for k, name in enumerate(names)}
    for ax in fig.axes:
        assert _marks(ax) == {x: n for x, n in per_source.items() if n}


def test_the_redraw_of_a_shipped_monte_carlo_study_counts_its_failed_rows():
    """model_mismatch's histogram (its only figure): the title counts the rows a guard
    rewrote ``failed``, and each histogram holds only the ``ok`` rows."""
    from drake_coop.studies.plots import _figure_hist

    rows = _rows("model_mismatch")
    n_bad = sum(r["status"] in NOT_OK for r in rows)
    assert n_bad == 11
    fig = _figure_hist(_shipped("model_mismatch"))
    assert f"{len(rows)} cases, {n_bad} diverged or failed" in fig._suptitle.get_text()
    for ax in fig.axes:
        assert sum(p.get_height() for p in ax.patches) == len(rows) - n_bad


def test_a_results_csv_that_is_not_its_study_file_is_refused_in_one_line(tmp_path):
    """A row whose parameter is not what the study file gives for its index, and a file
    without the store's columns: one line naming the row and the column."""
    from drake_coop.studies.plots import plot_results, results_document

    text = (ROOT / "docs/figures/studies/velocity_estimation_results.csv").read_text()
    lines = text.splitlines(keepends=True)
    lines[5] = lines[5].replace(",1048576,", ",2048,", 1)
    assert lines[5] != text.splitlines(keepends=True)[5]
    changed = tmp_path / "results.csv"
    changed.write_text("".join(lines))
    study = ROOT / "studies/velocity_estimation.yaml"
    with pytest.raises(ValueError, match=r"row '4': robots\.\*\.encoders\.counts_per_rev is "
                                         r"'2048', the study file .* gives '1048576'") as err:
        results_document(study, changed)
    assert "\n" not in str(err.value)
    bare = tmp_path / "bare.csv"
    bare.write_text("index,status\n0,ok\n")
    with pytest.raises(ValueError, match="not a study's results.csv .* missing hash"):
        plot_results(study, bare, tmp_path)
    assert not list(tmp_path.glob("*.png"))
