"""Diagram export (.dot/.svg) and the self-contained Meshcat HTML replay."""

from __future__ import annotations

import base64
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from drake_coop.results import export
from drake_coop.results import io as results_io

pytest.importorskip("pydrake")

from pydrake.geometry import Meshcat, Sphere  # noqa: E402
from pydrake.math import RigidTransform  # noqa: E402
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph  # noqa: E402
from pydrake.multibody.tree import SpatialInertia  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402
from pydrake.systems.primitives import ConstantVectorSource  # noqa: E402

HAVE_DOT = shutil.which("dot") is not None


def falling_sphere(replay: bool = False):
    """A MultibodyPlant with one free sphere, a constant source; optionally a replay."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    plant.set_name("falling_plant")
    ball = plant.AddRigidBody("ball", SpatialInertia.SolidSphereWithMass(1.0, 0.05))
    plant.RegisterVisualGeometry(ball, RigidTransform(), Sphere(0.05), "ball_visual",
                                 [0.8, 0.1, 0.1, 1.0])
    plant.Finalize()
    builder.AddNamedSystem("command_source", ConstantVectorSource([1.0, 2.0]))
    recorder = export.MeshcatReplay.add_to_builder(builder, scene_graph) if replay else None
    return builder.Build(), recorder


def leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


def test_dot_names_the_subsystems(tmp_path):
    diagram, _ = falling_sphere()
    files = export.write_diagram(diagram, tmp_path / "out")
    assert files["dot"] == tmp_path / "out" / "system_diagram.dot"
    text = files["dot"].read_text()
    assert text.lstrip().startswith("digraph")
    for name in ("falling_plant", "scene_graph", "command_source"):
        assert name in text
    if HAVE_DOT:
        assert files["svg"] == tmp_path / "out" / "system_diagram.svg"
    assert not [n for n in leftovers(tmp_path / "out") if n.endswith(".tmp")]


def test_max_depth_limits_the_expansion(tmp_path):
    diagram, _ = falling_sphere()
    full = export.write_diagram(diagram, tmp_path, "full")["dot"].read_text()
    shallow = export.write_diagram(diagram, tmp_path, "shallow", max_depth=0)["dot"]
    assert shallow.read_text() != full


@pytest.mark.skipif(not HAVE_DOT, reason="graphviz's dot is not installed")
def test_svg_is_valid_xml(tmp_path):
    diagram, _ = falling_sphere()
    files = export.write_diagram(diagram, tmp_path, "d")
    svg = files["svg"].read_text()
    assert "<svg" in svg
    assert ET.fromstring(svg).tag.endswith("svg")
    assert "command_source" in svg
    assert leftovers(tmp_path) == ["d.dot", "d.svg"]


@pytest.mark.skipif(not HAVE_DOT, reason="graphviz's dot is not installed")
def test_subsystem_diagram(tmp_path):
    diagram, _ = falling_sphere()
    plant = diagram.GetSubsystemByName("falling_plant")
    files = export.write_subsystem_diagram(plant, tmp_path, "plant")
    assert "falling_plant" in files["dot"].read_text()
    assert ET.parse(files["svg"]).getroot().tag.endswith("svg")


def test_without_graphviz_the_dot_is_written_and_a_warning_says_so(tmp_path, monkeypatch):
    diagram, _ = falling_sphere()
    monkeypatch.setattr(export.shutil, "which", lambda name: None)
    with pytest.warns(UserWarning, match=r"graphviz.*dot.*missing.*graphviz"):
        files = export.write_diagram(diagram, tmp_path, "d")
    assert files["svg"] is None
    assert "command_source" in files["dot"].read_text()
    assert leftovers(tmp_path) == ["d.dot"]


def test_failing_renderer_leaves_no_svg_nor_temp_file(tmp_path, monkeypatch):
    diagram, _ = falling_sphere()
    monkeypatch.setattr(export.shutil, "which", lambda name: "/usr/bin/dot")

    def broken_dot(cmd, **kwargs):
        Path(cmd[-1]).write_text("<svg partial")   # half a file in the temporary path
        raise subprocess.CalledProcessError(1, cmd, b"", b"dot: syntax error")

    monkeypatch.setattr(export.subprocess, "run", broken_dot)
    with pytest.raises(RuntimeError, match="syntax error"):
        export.write_diagram(diagram, tmp_path, "d")
    assert leftovers(tmp_path) == ["d.dot"]   # the .dot is whole; no .svg, no temp file


def test_failing_write_keeps_the_previous_file_and_no_temp(tmp_path, monkeypatch):
    diagram, _ = falling_sphere()
    target = tmp_path / "d.dot"
    target.write_text("previous")

    def broken_write(self, data):
        with open(self, "wb") as f:
            f.write(data[:10])   # partial write, then the disk fills up
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(results_io.Path, "write_bytes", broken_write)
    with pytest.raises(OSError, match="No space"):
        export.write_diagram(diagram, tmp_path, "d")
    monkeypatch.undo()
    assert target.read_text() == "previous"
    assert leftovers(tmp_path) == ["d.dot"]


def simulate_replay(path: Path, t_end: float = 0.2) -> Path:
    diagram, recorder = falling_sphere(replay=True)
    simulator = Simulator(diagram)
    recorder.start()
    simulator.AdvanceTo(t_end)
    return recorder.finish(path)


def embedded_payload(html: str) -> bytes:
    """The scene and the animation: base64 msgpack in ``data:`` URIs inside the HTML."""
    chunks = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    assert chunks, "no embedded scene data"
    return b"".join(base64.b64decode(c) for c in chunks)


def test_meshcat_replay_is_a_self_contained_html(tmp_path):
    path = simulate_replay(tmp_path / "replay" / "replay.html")
    assert path == tmp_path / "replay" / "replay.html"
    html = path.read_text()
    assert path.stat().st_size > 10_000
    assert "<html" in html
    # Verified on drake 1.51.1: StaticHtml inlines the whole viewer (meshcat.js, ~2 MB) in
    # bare <script> tags; nothing is loaded from a URL. (The inlined JS mentions a CDN only
    # for WebXR controller models, which a desktop browser never fetches.)
    tags = re.findall(r"<(?:script|link|img|iframe)\b[^>]*>", html, flags=re.I)
    assert any(t.lower().startswith("<script") for t in tags)
    assert not [t for t in tags if re.search(r"\b(?:src|href)\s*=", t, flags=re.I)]
    assert not re.search(r"<script[^>]*src\s*=\s*[\"']?https?://", html, flags=re.I)
    assert not re.search(r"import\s*\(?\s*[\"']https?://", html)
    payload = embedded_payload(html)
    assert b"set_object" in payload and b"/drake/visualizer/ball/ball_vis" in payload
    assert payload.count(b"set_animation") == 1   # the recorded motion
    assert leftovers(path.parent) == ["replay.html"]


def test_several_replays_in_one_process(tmp_path):
    first = simulate_replay(tmp_path / "a.html", 0.1)
    second = simulate_replay(tmp_path / "b.html", 0.2)
    assert export.shared_meshcat() is export.shared_meshcat()
    assert first.stat().st_size > 10_000 and second.stat().st_size > 10_000
    a, b = embedded_payload(first.read_text()), embedded_payload(second.read_text())
    assert a != b   # the second replay holds its own (longer) recording, once
    assert a.count(b"set_animation") == b.count(b"set_animation") == 1
    assert b.count(b"set_object") == 1   # the first run's scene was cleared


def test_failing_html_write_leaves_nothing(tmp_path, monkeypatch):
    diagram, recorder = falling_sphere(replay=True)
    recorder.start()
    Simulator(diagram).AdvanceTo(0.05)

    def broken_write(self, data):
        with open(self, "wb") as f:
            f.write(data[:1000])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(results_io.Path, "write_bytes", broken_write)
    with pytest.raises(OSError):
        recorder.finish(tmp_path / "replay.html")
    assert leftovers(tmp_path) == []


def test_add_meshcat_returns_the_shared_meshcat():
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    plant.Finalize()
    meshcat = export.add_meshcat(builder, scene_graph, publish_period=0.05)
    assert isinstance(meshcat, Meshcat) and meshcat is export.shared_meshcat()
    builder.Build()
