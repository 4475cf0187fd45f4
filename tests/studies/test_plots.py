"""A study figure against a categorical parameter (names, variants) draws categories: no line
or band joins two categories, and no tick label overlaps another."""

from __future__ import annotations

import numpy as np
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
