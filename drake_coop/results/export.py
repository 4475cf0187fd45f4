"""Exports of a run: the system diagram (Graphviz) and a self-contained Meshcat replay.

* :func:`write_diagram` writes ``<name>.dot`` from ``System.GetGraphvizString`` and renders
  ``<name>.svg`` with graphviz's ``dot`` when it is installed (Debian package ``graphviz``);
  without it, a warning says so and the ``.dot`` is still written.
* :class:`MeshcatReplay` records the simulation with a ``MeshcatVisualizer`` and writes
  ``Meshcat.StaticHtml()``: one HTML file with the scene, the animation and the viewer's
  JavaScript inlined, which opens offline in a browser (no server, no network).
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import warnings
from pathlib import Path

from drake_coop.results.io import atomic_path, atomic_write_text

_MESHCAT = None


def _render_svg(dot_text: str, path: Path) -> Path | None:
    exe = shutil.which("dot")
    if exe is None:
        warnings.warn("graphviz's `dot` is missing: wrote the .dot only, no .svg "
                      "(install the Debian package graphviz)", stacklevel=3)
        return None
    with atomic_path(path) as tmp:
        subprocess.run([exe, "-Tsvg", "-o", str(tmp)], input=dot_text.encode(), check=True,
                       timeout=60, capture_output=True)
    return path


def write_diagram(system, out_dir: str | Path, name: str = "system_diagram",
                  max_depth: int | None = None) -> dict[str, Path | None]:
    """Write a System's diagram as ``<name>.dot`` and, with graphviz, ``<name>.svg``.

    Parameters
    ----------
    system : pydrake.systems.framework.System
        A Diagram (or any System).
    out_dir : path
    name : str
        File stem.
    max_depth : int, optional
        Depth of sub-diagrams to expand (None: all).
    """
    out = Path(out_dir)
    text = (system.GetGraphvizString() if max_depth is None
            else system.GetGraphvizString(max_depth=max_depth))
    dot = atomic_write_text(out / f"{name}.dot", text)
    return {"dot": dot, "svg": _render_svg(text, out / f"{name}.svg")}


def write_subsystem_diagram(system, out_dir: str | Path, name: str) -> dict[str, Path | None]:
    """:func:`write_diagram` of a sub-diagram (e.g. one robot's control block), fully expanded."""
    return write_diagram(system, out_dir, name, max_depth=None)


def shared_meshcat():
    """One Meshcat per process (each opens a loopback port); cleared for every new replay."""
    global _MESHCAT
    if _MESHCAT is None:
        from pydrake.geometry import Meshcat

        # No "Meshcat listening for connections" line: here it only records.
        logger = logging.getLogger("drake")
        previous = logger.level
        logger.setLevel(logging.WARNING)
        try:
            _MESHCAT = Meshcat()
        finally:
            logger.setLevel(previous)
    return _MESHCAT


class MeshcatReplay:
    """Record a simulation in Meshcat and save it as a self-contained HTML file.

    Use: ``replay = MeshcatReplay.add_to_builder(builder, scene_graph)`` before ``Build()``,
    ``replay.start()`` before simulating, ``replay.finish(path)`` after.
    """

    def __init__(self, meshcat, visualizer):
        self.meshcat = meshcat
        self.visualizer = visualizer

    @classmethod
    def add_to_builder(cls, builder, scene_graph, publish_period: float = 1 / 30
                       ) -> "MeshcatReplay":
        """Add a MeshcatVisualizer (illustration geometry) to ``builder``."""
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

        meshcat = shared_meshcat()
        meshcat.Delete()
        meshcat.DeleteRecording()
        params = MeshcatVisualizerParams()
        params.publish_period = publish_period
        visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
        return cls(meshcat, visualizer)

    def start(self) -> None:
        """Start recording (frames are kept, not streamed)."""
        self.visualizer.StartRecording(set_transforms_while_recording=False)

    def finish(self, path: str | Path) -> Path:
        """Stop recording, publish it and write the self-contained HTML atomically."""
        self.visualizer.StopRecording()
        self.visualizer.PublishRecording()
        return atomic_write_text(path, self.meshcat.StaticHtml())
