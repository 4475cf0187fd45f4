"""``drake-coop plot`` draws the block diagrams' SVG that a run without graphviz could not."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from drake_coop.cli import main
from drake_coop.results.export import draw_missing_svgs


def _fake_dot(folder: Path) -> None:
    """A ``dot`` on PATH that writes the graph's source into the SVG it is asked for."""
    exe = folder / "dot"
    exe.write_text("#!/bin/sh\n# dot -Tsvg -o OUT < source\n"
                   'out="$3"; { echo "<svg>"; /bin/cat; echo "</svg>"; } > "$out"\n')
    exe.chmod(0o755)


def test_missing_svgs_are_drawn_once_graphviz_is_there(tmp_path, monkeypatch):
    (tmp_path / "a.dot").write_text("digraph { x -> y }\n")
    (tmp_path / "b.dot").write_text("digraph { u -> v }\n")
    (tmp_path / "b.svg").write_text("<svg>kept</svg>")
    monkeypatch.setenv("PATH", str(tmp_path / "nobin"))
    assert draw_missing_svgs(tmp_path) == []                  # no graphviz: nothing, quietly
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    _fake_dot(bin_)
    monkeypatch.setenv("PATH", str(bin_))
    assert draw_missing_svgs(tmp_path) == [tmp_path / "a.svg"]
    assert "x -> y" in (tmp_path / "a.svg").read_text()
    assert (tmp_path / "b.svg").read_text() == "<svg>kept</svg>"


@pytest.mark.slow
def test_plot_draws_the_svg_a_run_without_graphviz_left_out(tmp_path, monkeypatch):
    out = tmp_path / "run"
    monkeypatch.setenv("PATH", str(tmp_path / "nobin"))        # no graphviz during the run
    monkeypatch.setenv("MPLBACKEND", "Agg")
    assert main(["run", "--out", str(out), "--t-end", "0.05", "--no-replay", "--quiet"]) == 0
    dots = sorted(out.glob("*.dot"))
    assert dots
    assert not [d for d in dots if d.with_suffix(".svg").exists()]
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    _fake_dot(bin_)
    monkeypatch.setenv("PATH", f"{bin_}{os.pathsep}{os.environ['PATH']}")
    assert main(["plot", str(out), "--quiet"]) == 0
    for dot in dots:
        svg = dot.with_suffix(".svg").read_text()
        assert svg.startswith("<svg>") and dot.read_text().strip() in svg


def test_replay_html_gets_a_time_label_reading_meshcats_animation_clock():
    from drake_coop.results.export import shared_meshcat, with_time_label

    html = shared_meshcat().StaticHtml()
    labelled = with_time_label(html)
    assert labelled.count('id="drake-coop-time"') == 1
    assert labelled.index("drake-coop-time") < labelled.rindex("</body>")
    # The label reads the viewer Meshcat's page declares, through its animator's clock.
    assert "var viewer = new MeshCat.Viewer" in html and "class Animator" in html
    assert "this.time=" in html.replace(" ", "")
    assert "viewer.animator.time" in labelled
    with pytest.raises(ValueError, match="no </body>"):
        with_time_label("<html>")
