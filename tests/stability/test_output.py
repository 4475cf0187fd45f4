"""The stability figures: the swept parameter with its unit, ρ with readable ticks."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from drake_coop.stability.output import plot_maps  # noqa: E402


def _figures(monkeypatch, tmp_path, rows, swept):
    kept = []
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))
    plot_maps(tmp_path, swept, rows)
    return [f for f in kept if f is not None]


def _y_ticks(ax) -> list[str]:
    ax.figure.canvas.draw()
    lo, hi = ax.get_ylim()
    return [t.get_text() for t in ax.get_yticklabels()
            if t.get_text() and lo <= t.get_position()[1] <= hi]


@pytest.mark.parametrize("rhos, scale", [
    ([0.98, 0.94, 0.90, 0.93, 2.2, 3.6, 7.1, 11.5], "log"),       # stable, then diverging
    ([1.0104, 0.9995, 0.9995, 0.9995, 0.9995, 0.9995, 0.9995, 0.9995], "linear"),
])
def test_rho_against_the_period_has_units_and_several_plain_ticks(monkeypatch, tmp_path,
                                                                    rhos, scale):
    periods = [0.009, 0.012, 0.016, 0.020, 0.025, 0.030, 0.040, 0.050]
    rows = [{"point": "free", "control_period": h, "rho": r} for h, r in zip(periods, rhos)]
    (fig,) = _figures(monkeypatch, tmp_path, rows, ["control_period"])
    ax = fig.axes[0]
    assert ax.get_xlabel() == "control period h [ms]"
    assert ax.get_xlim()[1] == pytest.approx(50, rel=0.1)          # drawn in ms
    assert ax.get_yscale() == scale
    ticks = _y_ticks(ax)
    assert len(ticks) >= 3, ticks
    assert all("^" not in t and "{" not in t for t in ticks), ticks   # no 10^x mathtext
