"""Exports of a run: the system diagram (Graphviz) and a self-contained Meshcat replay.

* :func:`write_diagram` writes ``<name>.dot`` — Drake's ``System.GetGraphvizString`` or, with
  ``style="connected"``, :func:`~drake_coop.results.graph.connected_graphviz` (connected ports
  only, left to right) — and renders ``<name>.svg`` with graphviz's ``dot`` when it is
  installed (Debian package ``graphviz``); without it, a warning says so and the ``.dot`` is
  still written.
* :class:`MeshcatReplay` records the simulation with a ``MeshcatVisualizer`` and writes
  ``Meshcat.StaticHtml()``: one HTML file with the scene, the animation and the viewer's
  JavaScript inlined (no ``<script src=...>``; the scene and the animation are embedded as a
  base64 ``data:`` URI), which opens offline in a browser (no server, no network).

Every file is written atomically (temporary file beside the target, then ``os.replace``): a
failure leaves neither a partial target nor a temporary file behind.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from drake_coop.results.io import atomic_path, atomic_write_text

if TYPE_CHECKING:
    from pydrake.geometry import Meshcat, MeshcatVisualizer, SceneGraph
    from pydrake.systems.framework import DiagramBuilder, System

__all__ = ["MeshcatReplay", "add_meshcat", "draw_missing_svgs", "live_meshcat",
           "with_time_label", "shared_meshcat", "write_diagram",
           "write_subsystem_diagram"]

DOT_TIMEOUT = 60.0
"""Seconds allowed to graphviz's ``dot`` for one rendering."""

_MESHCAT: Meshcat | None = None


def _render_svg(dot_text: str, path: Path) -> Path | None:
    """Render ``dot_text`` to ``path`` with graphviz's ``dot``; None (and a warning) without it.

    Parameters
    ----------
    dot_text : str
        Graphviz source.
    path : Path
        Target ``.svg``; written atomically.

    Returns
    -------
    Path or None
        ``path``, or None when ``dot`` is not installed.

    Raises
    ------
    RuntimeError
        If ``dot`` fails or times out (no ``.svg`` is left behind).
    """
    exe = shutil.which("dot")
    if exe is None:
        warnings.warn(f"graphviz's `dot` is missing: wrote the .dot only, {path.name} was not "
                      "drawn (install the Debian package graphviz)", UserWarning, stacklevel=3)
        return None
    with atomic_path(path) as tmp:
        try:
            subprocess.run([exe, "-Tsvg", "-o", str(tmp)], input=dot_text.encode("utf-8"),
                           check=True, timeout=DOT_TIMEOUT, capture_output=True)
        except subprocess.CalledProcessError as exc:
            err = exc.stderr.decode("utf-8", "replace").strip()
            raise RuntimeError(f"graphviz's dot failed on {path.name}: {err}") from exc
        except subprocess.TimeoutExpired as exc:
            raise RuntimeError(f"graphviz's dot took over {DOT_TIMEOUT:g} s on {path.name}"
                               ) from exc
    return path


TIME_LABEL = """
<div id="drake-coop-time" style="position: fixed; left: 12px; bottom: 12px; z-index: 10;
  font: 16px monospace; background: rgba(255, 255, 255, 0.8); padding: 2px 6px;">t = 0.00 s</div>
<script>
  // drake_coop: the replay's simulated time (Meshcat's animation clock, in seconds).
  (function () {
    var label = document.getElementById("drake-coop-time");
    function show() {
      if (typeof viewer !== "undefined" && viewer.animator && isFinite(viewer.animator.time)) {
        label.textContent = "t = " + Number(viewer.animator.time).toFixed(2) + " s";
      }
      requestAnimationFrame(show);
    }
    show();
  })();
</script>
"""
"""A label in the corner of the HTML replay showing the animation's time (simulated seconds)."""


def with_time_label(html: str) -> str:
    """Meshcat's static HTML with :data:`TIME_LABEL` added before ``</body>``.

    Parameters
    ----------
    html : str
        Meshcat's static HTML.

    Returns
    -------
    str
        The HTML with the label.

    Raises
    ------
    ValueError
        If the HTML has no ``</body>`` (not Meshcat's page).
    """
    head, sep, tail = html.rpartition("</body>")
    if not sep:
        raise ValueError("html: no </body> to add the time label before")
    return head + TIME_LABEL + sep + tail


def draw_missing_svgs(out_dir: str | Path) -> list[Path]:
    """Draw the ``.svg`` of every ``.dot`` in ``out_dir`` that has none (a run written before
    graphviz was installed), when graphviz's ``dot`` is installed now.

    Parameters
    ----------
    out_dir : str or Path
        A run's folder.

    Returns
    -------
    list of Path
        The ``.svg`` files drawn (empty without ``dot``: no warning, the run already gave one).
    """
    if shutil.which("dot") is None:
        return []
    drawn = []
    for dot in sorted(Path(out_dir).glob("*.dot")):
        svg = dot.with_suffix(".svg")
        if not svg.exists():
            drawn.append(_render_svg(dot.read_text(encoding="utf-8"), svg))
    return drawn


def write_diagram(diagram: System, out_dir: str | Path, name: str = "system_diagram",
                  max_depth: int | None = None, style: str = "drake"
                  ) -> dict[str, Path | None]:
    """Write a diagram as ``<name>.dot`` and, with graphviz, ``<name>.svg``.

    Parameters
    ----------
    diagram : pydrake.systems.framework.System
        A Diagram (or any System).
    out_dir : str or Path
        Output directory (created if needed).
    name : str
        File stem.
    max_depth : int, optional
        Depth of sub-diagrams to expand (None: all), for ``style="drake"``.
    style : str
        ``"drake"`` (every port, Drake's picture), ``"connected"`` (a Diagram one level
        deep, connected ports only, each loop left to right; see
        :mod:`drake_coop.results.graph`) or ``"paper"`` (the paper's block diagram of the
        experiment, per robot, with equation numbers; see
        :mod:`drake_coop.results.block_diagram`).

    Returns
    -------
    dict
        ``{"dot": Path, "svg": Path or None}``; ``svg`` is None when graphviz's ``dot`` is
        missing, in which case a ``UserWarning`` is emitted.
    """
    out = Path(out_dir)
    if style == "connected":
        from drake_coop.results.graph import connected_graphviz

        text = connected_graphviz(diagram)
    elif style == "paper":
        from drake_coop.results.block_diagram import paper_block_diagram

        text = paper_block_diagram(diagram)
    elif style == "drake":
        text = (diagram.GetGraphvizString() if max_depth is None
                else diagram.GetGraphvizString(max_depth=max_depth))
    else:
        raise ValueError(f"style must be 'drake', 'connected' or 'paper', got {style!r}")
    dot = atomic_write_text(out / f"{name}.dot", text)
    return {"dot": dot, "svg": _render_svg(text, out / f"{name}.svg")}


def write_subsystem_diagram(system: System, out_dir: str | Path, name: str,
                            style: str = "drake") -> dict[str, Path | None]:
    """:func:`write_diagram` of one subsystem (a sub-diagram or a LeafSystem), fully expanded.

    Parameters
    ----------
    system : pydrake.systems.framework.System
        E.g. one robot's control block, taken from the built diagram.
    out_dir : str or Path
        Output directory.
    name : str
        File stem.
    style : str
        As :func:`write_diagram` (``"connected"`` needs a Diagram).

    Returns
    -------
    dict
        As :func:`write_diagram`.
    """
    return write_diagram(system, out_dir, name, max_depth=None, style=style)


def shared_meshcat() -> Meshcat:
    """The process's one Meshcat, created on first use (it opens a loopback port).

    Returns
    -------
    pydrake.geometry.Meshcat
        Reused by every replay; :meth:`MeshcatReplay.add_to_builder` clears it.
    """
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


def live_meshcat() -> Meshcat:
    """A Meshcat server for watching a run live (``drake-coop run --meshcat``).

    Created with :func:`pydrake.geometry.StartMeshcat` (which also serves Deepnote) and made
    the process's shared Meshcat, so that the HTML replay records the same scene.

    Returns
    -------
    pydrake.geometry.Meshcat
        Its ``web_url()`` is the address to open; nothing waits for a browser.
    """
    global _MESHCAT
    if _MESHCAT is None:
        from pydrake.geometry import StartMeshcat

        logger = logging.getLogger("drake")
        previous = logger.level
        logger.setLevel(logging.WARNING)   # the caller prints the URL itself
        try:
            _MESHCAT = StartMeshcat()
        finally:
            logger.setLevel(previous)
    return _MESHCAT


def _add_visualizer(builder: DiagramBuilder, scene_graph: SceneGraph, publish_period: float
                    ) -> tuple[Meshcat, MeshcatVisualizer]:
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role

    meshcat = shared_meshcat()
    meshcat.Delete()            # the previous run's scene
    meshcat.DeleteRecording()   # and its frames
    params = MeshcatVisualizerParams()
    params.publish_period = publish_period
    params.role = Role.kIllustration
    visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
    return meshcat, visualizer


def add_meshcat(builder: DiagramBuilder, scene_graph: SceneGraph, *,
                publish_period: float = 1 / 30) -> Meshcat:
    """Add a MeshcatVisualizer (illustration geometry) on the shared headless Meshcat.

    Parameters
    ----------
    builder : pydrake.systems.framework.DiagramBuilder
        Not yet built.
    scene_graph : pydrake.geometry.SceneGraph
        The SceneGraph in ``builder``.
    publish_period : float
        Seconds between published frames.

    Returns
    -------
    pydrake.geometry.Meshcat
        The shared Meshcat (cleared of any previous scene and recording).
    """
    return _add_visualizer(builder, scene_graph, publish_period)[0]


class MeshcatReplay:
    """Record a simulation in Meshcat and save it as a self-contained HTML file.

    Use: ``replay = MeshcatReplay.add_to_builder(builder, scene_graph)`` before ``Build()``,
    ``replay.start()`` before simulating, ``replay.finish(path)`` after. All replays share the
    process's Meshcat (:func:`shared_meshcat`), so record one simulation at a time.

    Parameters
    ----------
    meshcat : pydrake.geometry.Meshcat
        Where the frames are recorded.
    visualizer : pydrake.geometry.MeshcatVisualizer
        The visualizer in the diagram.
    live : bool
        Also draw the recorded frames as they come (a live Meshcat, see :func:`live_meshcat`).
    """

    def __init__(self, meshcat: Meshcat, visualizer: MeshcatVisualizer, live: bool = False
                 ) -> None:
        self.meshcat = meshcat
        self.visualizer = visualizer
        self.live = live

    @classmethod
    def add_to_builder(cls, builder: DiagramBuilder, scene_graph: SceneGraph,
                       publish_period: float = 1 / 30, live: bool = False) -> MeshcatReplay:
        """Add a MeshcatVisualizer (illustration geometry) to ``builder``.

        Parameters
        ----------
        builder : pydrake.systems.framework.DiagramBuilder
            Not yet built.
        scene_graph : pydrake.geometry.SceneGraph
            The SceneGraph in ``builder``.
        publish_period : float
            Seconds between recorded frames.
        live : bool
            Draw the frames live too (on the shared Meshcat, see :func:`live_meshcat`).

        Returns
        -------
        MeshcatReplay
            The recorder, to save after the run.
        """
        return cls(*_add_visualizer(builder, scene_graph, publish_period), live=live)

    def start(self) -> None:
        """Start recording (frames are kept, and streamed only when ``live``)."""
        self.visualizer.StartRecording(set_transforms_while_recording=self.live)

    def finish(self, path: str | Path) -> Path:
        """Stop recording, publish it and write the self-contained HTML atomically.

        Parameters
        ----------
        path : str or Path
            Target ``.html`` (parent directories are created).

        Returns
        -------
        Path
            ``path``.
        """
        self.visualizer.StopRecording()
        self.visualizer.PublishRecording()
        return atomic_write_text(path, with_time_label(self.meshcat.StaticHtml()))
