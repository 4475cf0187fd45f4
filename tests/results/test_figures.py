"""Figure files: valid PNG and SVG for full and stopped runs, panels and labels, replot."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import matplotlib
import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from drake_coop.results import (
    compute_metrics,
    fig_references,
    plot_figures,
    replot,
    save_logs,
)
from tests.results.test_io import synthetic_run

ROOT_DIR = __import__("pathlib").Path(__file__).resolve().parents[2]

FIGURES = ["fig2_tracking_errors", "fig3_force_tracking", "fig4_force_estimate",
           "fig5_aux_force_error", "fig6_observation_errors", "fig_force_errors"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SVG_NS = "{http://www.w3.org/2000/svg}"


def check_png(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and len(data) > 10_000
    height, width, channels = matplotlib.image.imread(path).shape
    assert channels in (3, 4)
    return height, width


def check_svg(path) -> ET.Element:
    root = ET.parse(path).getroot()
    assert root.tag == f"{SVG_NS}svg"
    assert root.get("width") == "720pt"          # 10 in
    return root


def svg_texts(path) -> str:
    """The SVG's text (drawn with ``svg.fonttype = none``), whitespace removed."""
    root = check_svg(path)
    return "".join("".join(e.itertext()) for e in root.iter(f"{SVG_NS}text")).replace(
        "\xa0", "").replace(" ", "").replace("\n", "")


def check_files(paths, names) -> dict[str, int]:
    """Every figure as a valid PNG and SVG 10 in wide; returns the PNG heights."""
    assert [p.name for p in paths] == [f"{n}.{f}" for n in names for f in ("png", "svg")]
    heights = {}
    for p in paths:
        if p.suffix == ".png":
            height, width = check_png(p)
            assert width == 1200                  # 10 in at 120 dpi
            heights[p.stem] = height
        else:
            check_svg(p)
    assert plt.get_fignums() == []               # nothing left open in pyplot
    return heights


def check_panels(out, phases: list[str], absent: list[str]) -> None:
    """Panel letters, axis labels and phase names of Figures 2–6 and the references."""
    text = {n: svg_texts(out / f"{n}.svg") for n in FIGURES + ["fig_references"]}
    for name in ("fig2_tracking_errors", "fig6_observation_errors"):
        assert all(f"({c})" in text[name] for c in "abcdef")
    for name in ("fig3_force_tracking", "fig4_force_estimate", "fig5_aux_force_error"):
        assert "(a)" in text[name] and "(b)" in text[name] and "(c)" not in text[name]
    assert all(f"({c})" in text["fig_references"] for c in "abcd")
    assert text["fig3_force_tracking"].count("F_x(squeeze)[N]") == 2
    assert text["fig4_force_estimate"].count("F_x(squeeze)[N]") == 2
    assert text["fig2_tracking_errors"].count("[mm]") == 6
    assert text["fig6_observation_errors"].count("[µrad]") == 6      # z of 1–3 µrad
    # λ − λ_d (0.1–0.5 N by phase) and λ − λ̂ (0.25 N) on their own scale: mN, four panels.
    assert text["fig_force_errors"].count("[mN]") == 4
    assert all(f"({c})" in text["fig_force_errors"] for c in "abcd")
    for name in FIGURES:
        assert "t[s]" in text[name]
        assert all(p in text[name] for p in phases)
        assert not any(p in text[name] for p in absent)


def test_full_run_draws_every_figure_with_its_panels(tmp_path):
    logs, meta = synthetic_run(h=0.03)
    with matplotlib.rc_context({"svg.fonttype": "none"}):   # text as <text>, not paths
        paths = plot_figures(logs, meta, tmp_path) + fig_references(logs, meta, tmp_path)
    heights = check_files(paths, FIGURES + ["fig_references"])
    assert heights == {"fig2_tracking_errors": 624, "fig3_force_tracking": 408,
                       "fig4_force_estimate": 408, "fig5_aux_force_error": 624,
                       "fig6_observation_errors": 624, "fig_force_errors": 624,
                       "fig_references": 792}
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
    check_panels(tmp_path, ["free", "lift", "circle", "put_down", "return"], [])


def test_run_stopped_at_20s_is_replotted_from_its_logs(tmp_path):
    logs, meta = synthetic_run(t_end=20.0, h=0.03)
    meta = {**meta, "status": "diverged", "message": "robot1 estimated force too large"}
    for log in logs.values():
        log["lambda_hat"][-10:] = np.nan
        log["q_hat"][-10:] = np.inf
    save_logs(tmp_path, logs, meta)
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        paths = replot(tmp_path)
    assert check_files(paths[:-1], FIGURES + ["fig_references"])["fig3_force_tracking"] == 408
    assert paths[-1] == tmp_path / "metrics.json"
    metrics = json.loads(paths[-1].read_text())
    assert metrics == compute_metrics(logs, meta)
    assert list(metrics["robot1"]) == ["free", "lift", "all"]
    assert metrics["robot2"]["lift"]["n_nonfinite"] == 10
    check_panels(tmp_path, ["free", "lift"], ["circle", "put_down", "return"])


def test_empty_run_still_draws_every_figure(tmp_path):
    logs, meta = synthetic_run(t_end=0.0)
    logs = {r: {k: v[:0] for k, v in log.items()} for r, log in logs.items()}
    paths = plot_figures(logs, meta, tmp_path, formats=("png",))
    assert len(paths) == 6 and all(check_png(p)[1] == 1200 for p in paths)


def test_unknown_format_is_refused_before_anything_is_written(tmp_path):
    logs, meta = synthetic_run(t_end=1.0)
    with pytest.raises(ValueError, match="unsupported figure formats \\['bmpx'\\]"):
        plot_figures(logs, meta, tmp_path, formats=("png", "bmpx"))
    with pytest.raises(ValueError, match="only: fig_object_mass not among"):
        plot_figures(logs, meta, tmp_path / "new", only=("fig2_tracking_errors",
                                                         "fig_object_mass"))
    assert list(tmp_path.iterdir()) == []


def test_failed_save_keeps_the_previous_figure_and_leaves_no_temporary(tmp_path, monkeypatch):
    logs, meta = synthetic_run(t_end=1.0)
    fig_references(logs, meta, tmp_path, formats=("png",))
    before = (tmp_path / "fig_references.png").read_bytes()

    def broken_savefig(self, fname, **kwargs):
        with open(fname, "wb") as f:
            f.write(PNG_SIGNATURE)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", broken_savefig)
    with pytest.raises(OSError, match="No space"):
        fig_references(logs, meta, tmp_path, formats=("png",))
    assert (tmp_path / "fig_references.png").read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["fig_references.png"]


def test_figures_use_the_units_a_reader_reads(tmp_path):
    # Sub-millimetre tracking errors in µm, velocity errors of mrad/s in mrad/s: no "×1e-3"
    # offset text on any axis; the largest value decides the unit (5 µm, 2 mrad/s here).
    logs, meta = synthetic_run(h=0.03)
    for log in logs.values():
        log["x"] = log["x_d"] + 5e-6
        log["qdot"] = np.zeros_like(log["q"])
        log["qdot_hat"] = log["qdot"] + 2e-3
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        plot_figures(logs, meta, tmp_path, formats=("svg",),
                     only=("fig2_tracking_errors", "fig7_velocity_estimate"))
    fig2 = svg_texts(tmp_path / "fig2_tracking_errors.svg")
    fig7 = svg_texts(tmp_path / "fig7_velocity_estimate.svg")
    assert fig2.count("[µm]") == 6 and "[mm]" not in fig2
    assert fig7.count("[mrad/s]") == 6 and "[rad/s]" not in fig7.replace("[mrad/s]", "")
    for text in (fig2, fig7):
        assert "1e" not in text and "×10" not in text


def test_fig6_and_fig7_name_the_figure_and_the_robot_of_each_panel(tmp_path):
    logs, meta = synthetic_run(h=0.03)
    for log in logs.values():
        log["qdot"], log["qdot_hat"] = np.zeros_like(log["q"]), np.ones_like(log["q"])
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        plot_figures(logs, meta, tmp_path, formats=("svg",),
                     only=("fig6_observation_errors", "fig7_velocity_estimate"))
    fig6 = svg_texts(tmp_path / "fig6_observation_errors.svg")
    fig7 = svg_texts(tmp_path / "fig7_velocity_estimate.svg")
    assert "Fig.7" in fig7 and "Fig.6" in fig6
    for robot in (1, 2):
        for joint in (1, 2, 3):
            # Panel title and y label: z_{i,j} with the robot's index i.
            assert fig6.count(f"z{robot},{joint}") == 2, (robot, joint)


def test_object_mass_figure_only_with_mass_shares_and_its_sum_line(tmp_path):
    logs, meta = synthetic_run(h=0.03)
    with pytest.raises(ValueError, match="only: fig_object_mass not among"):
        plot_figures(logs, meta, tmp_path / "a", formats=("png",), only=("fig_object_mass",))
    for k, log in enumerate(logs.values()):
        log["mass_share"] = np.full(log["t"].shape, 0.2 + 0.1 * k)
    fig = __import__("drake_coop.results.figures", fromlist=["_object_mass"])._object_mass(
        logs, meta)
    lines = fig.axes[0].get_lines()
    sums = [ln for ln in lines if ln.get_label().startswith(r"$\sum")]
    expected = sum(0.2 + 0.1 * k for k in range(len(logs)))
    assert len(sums) == 1 and np.allclose(sums[0].get_ydata(), expected)
    paths = plot_figures(logs, meta, tmp_path / "b", formats=("png",), only=("fig_object_mass",))
    assert [p.stem for p in paths] == ["fig_object_mass"]
    check_png(paths[0])


def _drawn_figures(monkeypatch, logs, meta, tmp_path, only=None) -> dict:
    """Per figure :func:`plot_figures` draws (drawn as saved, texts laid out, before it is
    cleared): per panel, the title's box and the phase names with their boxes."""
    import drake_coop.results.figures as figures_module

    captured = {}

    def keep(fig, out_dir, name, formats):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        captured[name] = [
            (ax.title.get_window_extent(renderer),
             [(t.get_text(), t.get_window_extent(renderer)) for t in ax.texts
              if t.get_gid() == figures_module.PHASE_LABEL]) for ax in fig.axes]
        return []

    monkeypatch.setattr(figures_module, "_save", keep)
    plot_figures(logs, meta, tmp_path, formats=("png",), only=only)
    return captured


def test_phase_names_do_not_overlap_on_the_papers_timeline(tmp_path, monkeypatch):
    """Figs. 2 and 6 printed "put_down" and "return" over each other, then touching (short
    phases on a third of the page): every phase name's drawn box clears its neighbours' by a
    gap, and the panel's title."""
    from drake_coop.experiment.simulate import phases
    from drake_coop.scenario import load_scenario

    timeline = phases(load_scenario(ROOT_DIR / "scenarios" / "paper.yaml"))
    t_end = float(timeline[-1][2])
    logs, meta = synthetic_run(t_end=t_end, h=0.05)
    meta["phases"] = [list(p) for p in timeline]
    names = [p[0] for p in timeline]
    assert "put_down" in names and "return" in names
    checked = ("fig2_tracking_errors", "fig6_observation_errors", "fig3_force_tracking")
    drawn = _drawn_figures(monkeypatch, logs, meta, tmp_path, only=checked)
    assert set(drawn) == set(checked)
    for name in checked:
        panels = [labels for _, labels in drawn[name] if labels]
        assert panels and all({text for text, _ in labels} >= {"put_down", "return"}
                              for labels in panels), name
        gap = 2.0 * 120 / 72                   # 2 pt at the figures' 120 dpi, in pixels
        for title, labels in drawn[name]:
            for i, (a, box_a) in enumerate(labels):
                assert not box_a.overlaps(title), (name, a, "title")
                for b, box_b in labels[i + 1:]:
                    # apart by at least the gap (names that touch read as "put_downreturn")
                    wide = Bbox.from_extents(box_a.x0 - gap, box_a.y0, box_a.x1 + gap, box_a.y1)
                    assert not wide.overlaps(box_b), (name, a, b)


def test_object_mass_figure_draws_the_true_mass_when_the_plant_has_a_body(tmp_path):
    import drake_coop.results.figures as figures_module

    logs, meta = synthetic_run(h=0.03)
    for k, log in enumerate(logs.values()):
        log["mass_share"] = np.full(log["t"].shape, 0.2 + 0.1 * k)
    fig = figures_module._object_mass(logs, dict(meta, object_mass=0.5))
    assert not [ln for ln in fig.axes[0].get_lines() if "true mass" in ln.get_label()]
    meta = dict(meta, object_mass=0.75, object_size=[0.1, 0.2, 0.1])
    fig = figures_module._object_mass(logs, meta)
    true = [ln for ln in fig.axes[0].get_lines() if "true mass" in ln.get_label()]
    assert len(true) == 1 and np.allclose(true[0].get_ydata(), 0.75)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "true mass m = 0.75 kg" in legend
