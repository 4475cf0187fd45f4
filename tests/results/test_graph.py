"""The connected-ports block diagram (``results/graph.py``), checked against the connection map."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    Demultiplexer,
    Gain,
    Integrator,
    LogVectorOutput,
    MatrixGain,
)

from drake_coop.results.graph import connected_graphviz
from drake_coop.experiment.plan import plan_run


def loop_diagram():
    """ref → sum → controller → plant → demux(3) → sensor → sum (feedback); demux outputs 1 and
    2 unconnected; a logger on the plant (a sink)."""
    b = DiagramBuilder()
    ref = b.AddNamedSystem("loop_reference", ConstantVectorSource([1.0]))
    total = b.AddNamedSystem("loop_sum", Adder(2, 1))
    ctrl = b.AddNamedSystem("loop_controller", Gain(2.0, 1))
    plant = b.AddNamedSystem("plant", Integrator(3))
    demux = b.AddNamedSystem("plant_outputs", Demultiplexer(3))
    sensor = b.AddNamedSystem("loop_sensor", Gain(-1.0, 1))
    b.Connect(ref.get_output_port(), total.get_input_port(0))
    b.Connect(total.get_output_port(), ctrl.get_input_port())
    mux_in = b.AddNamedSystem("loop_spread", MatrixGain(np.ones((3, 1))))
    b.Connect(ctrl.get_output_port(), mux_in.get_input_port())
    b.Connect(mux_in.get_output_port(), plant.get_input_port())
    b.Connect(plant.get_output_port(), demux.get_input_port())
    b.Connect(demux.get_output_port(0), sensor.get_input_port())
    b.Connect(sensor.get_output_port(), total.get_input_port(1))
    LogVectorOutput(plant.get_output_port(), b).set_name("plant_logger")
    diagram = b.Build()
    diagram.set_name("loop")
    return diagram


def parse(dot: str):
    """Nodes' drawn port cells, edges (with their attributes), from the DOT text."""
    nodes = {}
    for node, label in re.findall(r"^\s*(s\d+) \[shape=plaintext, label=<(.*)>\];$", dot, re.M):
        name = re.search(r"<B>(.*?)</B>", label).group(1)
        nodes[node] = (name, set(re.findall(r'PORT="([uy]\d+)"', label)))
    edges = re.findall(r"^\s*(\S+) -> (\S+?)( \[constraint=false\])?;$", dot, re.M)
    return nodes, edges


def expected_ports(diagram):
    """Per subsystem name, the ports a connection between non-sink systems uses."""
    drawn = {id(s) for s in diagram.GetSystems() if s.num_output_ports() > 0}
    ports = {s.get_name(): set() for s in diagram.GetSystems() if id(s) in drawn}
    for (dst, i), (src, o) in diagram.connection_map().items():
        if id(dst) in drawn and id(src) in drawn:
            ports[dst.get_name()].add(f"u{int(i)}")
            ports[src.get_name()].add(f"y{int(o)}")
    return ports


def test_only_connected_ports_are_drawn_and_sinks_are_counted():
    diagram = loop_diagram()
    dot = connected_graphviz(diagram)
    nodes, edges = parse(dot)
    assert {name: ports for name, ports in nodes.values()} == expected_ports(diagram)
    assert nodes and all(name != "plant_logger" for name, _ in nodes.values())
    assert "not drawn: 1 VectorLogSink" in dot
    # Demultiplexer: 3 outputs, only y0 is connected.
    assert dict(nodes.values())["plant_outputs"] == {"u0", "y0"}
    assert len(edges) == sum(1 for (dst, _), (src, _) in diagram.connection_map().items()
                             if dst.num_output_ports() and src.num_output_ports())


def test_the_feedback_edge_does_not_constrain_the_left_to_right_order():
    nodes, edges = parse(connected_graphviz(loop_diagram()))
    node_of = {name: node for node, (name, _) in nodes.items()}
    unconstrained = {(a.split(":")[0], b.split(":")[0]) for a, b, flag in edges if flag}
    assert unconstrained == {(node_of["loop_sensor"], node_of["loop_sum"])}


def test_name_prefixes_group_and_exported_ports_sit_at_the_ends():
    inner = loop_diagram()
    sub = DiagramBuilder()
    gain = sub.AddNamedSystem("k", Gain(3.0, 1))
    sub.ExportInput(gain.get_input_port(), "u")
    sub.ExportOutput(gain.get_output_port(), "y")
    block = sub.Build()
    block.set_name("block")
    dot = connected_graphviz(block)
    assert re.search(r'"in_u" \[shape=cds', dot) and re.search(r'"out_y" \[shape=cds', dot)
    assert "{ rank=source; \"in_u\"; }" in dot and "{ rank=sink; \"out_y\"; }" in dot
    assert "cluster" not in dot               # one system: no group box
    outer = connected_graphviz(inner)
    assert 'subgraph "cluster_loop" { label="loop"' in outer   # loop_* grouped
    assert 'cluster_plant"' in outer          # plant and plant_outputs


@pytest.mark.skipif(shutil.which("dot") is None, reason="graphviz's dot is not installed")
def test_graphviz_renders_it():
    svg = subprocess.run(["dot", "-Tsvg"], input=connected_graphviz(loop_diagram()), text=True,
                         capture_output=True, check=True).stdout
    assert "<svg" in svg and "loop_controller" in svg


def test_experiment_picture_hides_the_plants_unconnected_ports():
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.scenario import default_scenario

    exp = build_experiment(plan_run(default_scenario()), log=True)
    plant = exp.coop.plant
    dot = connected_graphviz(exp.diagram)
    nodes, _ = parse(dot)
    drawn = dict(nodes.values())
    assert drawn == expected_ports(exp.diagram)
    n_plant_ports = plant.num_input_ports() + plant.num_output_ports()
    assert len(drawn["plant"]) < n_plant_ports / 3          # most of Drake's ports are idle
    assert "WorldModelInstance" not in dot and "VectorLogSink" in dot
    for name in ("robot1_reference", "robot1_control", "robot2_control", "scene_graph"):
        assert name in drawn


# ---------------------------------------------------------------- the paper's block diagram


def _block_graph(scenario):
    """(block name -> label, set of (source name, target name, label)) of the paper's block
    diagram of ``scenario``'s experiment, with its loggers; ``dir=back`` edges turned around."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.results.block_diagram import paper_block_diagram

    dot = paper_block_diagram(build_experiment(plan_run(scenario), log=True).diagram)
    names = {}
    for node, label in re.findall(r"^\s*(n\d+) \[label=<(.*)>, fillcolor", dot, re.M):
        system = re.search(r'COLOR="#667788">(.*?)</FONT>', label).group(1)
        names[node] = (system, re.sub(r"<[^>]+>", " ", label.split("<FONT")[0]).split())
    edges = set()
    for a, b, attrs in re.findall(r"^\s*(n\d+) -> (n\d+) \[(.*)\];$", dot, re.M):
        if "dir=back" in attrs:
            a, b = b, a
        edges.add((names[a][0], names[b][0]))
        if "dir=both" in attrs:
            edges.add((names[b][0], names[a][0]))
    return {system: " ".join(words) for system, words in names.values()}, edges


def test_paper_block_diagram_draws_each_robots_loop_with_equation_numbers():
    from drake_coop.scenario import default_scenario

    blocks, edges = _block_graph(default_scenario())
    for r in ("robot1", "robot2"):
        assert blocks[f"{r}_controller"].startswith("controller (13)")
        assert blocks[f"{r}_velocity_observer"].startswith("velocity observer (15)–(16)")
        assert blocks[f"{r}_force_observer"].startswith("force observer (22)")
        assert blocks[f"{r}_reference"].startswith("reference (28)–(29)")
        # The loop, as the Diagram connects it: reference → controller → actuators → plant →
        # encoders → controller and both observers; controller ⇄ velocity observer.
        for edge in [(f"{r}_reference", f"{r}_controller"),
                     (f"{r}_controller", f"{r}_actuators"), (f"{r}_actuators", "plant"),
                     ("plant", f"{r}_encoders"), (f"{r}_encoders", f"{r}_controller"),
                     (f"{r}_encoders", f"{r}_velocity_observer"),
                     (f"{r}_encoders", f"{r}_force_observer"),
                     (f"{r}_velocity_observer", f"{r}_controller"),
                     (f"{r}_controller", f"{r}_velocity_observer"),
                     (f"{r}_force_observer", f"{r}_controller")]:
            assert edge in edges, edge
    # Loggers, the scene graph and the ground-truth sensors that only feed the logs are out.
    assert set(blocks) == {f"{r}_{b}" for r in ("robot1", "robot2") for b in (
        "controller", "velocity_observer", "force_observer", "reference", "encoders",
        "actuators")} | {"plant"}


def test_paper_block_diagram_follows_the_sources_a_scenario_chooses():
    from drake_coop.scenario import default_scenario

    s = default_scenario()
    s.robots[0].force_source, s.robots[0].velocity_source = "sensor", "measured"
    blocks, edges = _block_graph(s)
    assert blocks["robot1_sensed_force"].startswith("force feedback")
    assert blocks["robot1_measured_velocity"].startswith("measured velocity")
    assert ("robot1_ft_sensor", "robot1_sensed_force") in edges    # the sensor now feeds (13)
    assert ("plant", "robot1_measured_velocity") in edges          # true velocities
    assert "robot2_ft_sensor" not in blocks                        # robot 2 keeps (22)


def _text_boxes(svg: str) -> list[tuple[str, str, tuple[float, float, float, float]]]:
    """(group title, text, box in points) of every text element of a graphviz SVG, its width
    measured in DejaVu Sans (wider than the Helvetica graphviz lays out with: a browser's
    substitute font must still fit)."""
    import xml.etree.ElementTree as ET

    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    ns = "{http://www.w3.org/2000/svg}"
    font = FontProperties(family="DejaVu Sans")
    boxes = []
    for group in ET.fromstring(svg).iter(f"{ns}g"):
        title = group.find(f"{ns}title")
        for t in group.findall(f"{ns}text"):
            text, size = "".join(t.itertext()), float(t.get("font-size"))
            x, y = float(t.get("x")), float(t.get("y"))
            width = TextPath((0, 0), text, size=size, prop=font).get_extents().width
            x0 = {"middle": x - width / 2, "end": x - width}.get(t.get("text-anchor"), x)
            boxes.append((title.text if title is not None else "", text,
                          (x0, y - 0.75 * size, x0 + width, y + 0.25 * size)))
    return boxes


def _overlapping(boxes) -> list[tuple[str, str]]:
    """Pairs of texts whose boxes overlap: of two groups (nodes, edges), or of one group on
    one line (the lines of one node are graphviz's own stacking, not compared)."""
    return [(a, b) for i, (ga, a, (ax0, ay0, ax1, ay1)) in enumerate(boxes)
            for gb, b, (bx0, by0, bx1, by1) in boxes[i + 1:]
            if (ga != gb or abs(ay1 - by1) < 1.0)
            and ax0 < bx1 and bx0 < ax1 and ay0 < by1 and by0 < ay1]


def _edge_points(svg: str, samples: int = 40) -> list[tuple[str, np.ndarray]]:
    """(edge title, points in points) along every edge path of a graphviz SVG: its cubic
    Bézier pieces (``M p0 C p1 p2 p3 p4 p5 p6 …``) sampled at ``samples`` points each."""
    import xml.etree.ElementTree as ET

    ns = "{http://www.w3.org/2000/svg}"
    t = np.linspace(0.0, 1.0, samples)[:, None]
    paths = []
    for group in ET.fromstring(svg).iter(f"{ns}g"):
        if group.get("class") != "edge":
            continue
        for path in group.findall(f"{ns}path"):
            p = np.array([float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", path.get("d"))])
            p = p.reshape(-1, 2)
            pieces = [(1 - t) ** 3 * p[i] + 3 * (1 - t) ** 2 * t * p[i + 1]
                      + 3 * (1 - t) * t ** 2 * p[i + 2] + t ** 3 * p[i + 3]
                      for i in range(0, len(p) - 3, 3)]
            paths.append((group.find(f"{ns}title").text, np.vstack(pieces)))
    return paths


def _edges_through_labels(svg: str, margin: float = 0.6) -> list[tuple[str, str]]:
    """(edge, text) pairs where an edge runs through a text: a point of the edge more than
    ``margin`` em inside the text's box from its left and its right end. Graphviz puts an
    edge's label against its edge at Helvetica's widths; measured in the wider DejaVu Sans a
    label may reach over its edge by a character (0.6 em), not more."""
    found, boxes = [], _text_boxes(svg)
    for edge, points in _edge_points(svg):
        for _, text, (x0, y0, x1, y1) in boxes:
            m = margin * (y1 - y0)                       # the box is 1 em high
            x, y = points[:, 0], points[:, 1]
            if np.any((x > x0 + m) & (x < x1 - m) & (y > y0) & (y < y1)):
                found.append((edge, text))
    return found


#: An edge of the paper's block diagram as the generator drew it before its labels were
#: fixed (graphviz 2.43's SVG, ``drake-coop diagram``): the controller ⇄ velocity observer
#: double arrow, one label for both directions mid-way on the curve, each ``<SUB>`` index a
#: text element of its own.
_OLD_DOUBLE_ARROW = """<svg xmlns="http://www.w3.org/2000/svg"><g class="edge">
<title>n1&#45;&gt;n3</title>
<path fill="none" stroke="black" d="M265.68,-287.05C223.96,-292.92 173.97,-307.93 147,-345 \
107.52,-399.27 216.68,-428.13 285.02,-440.5"/>
<text text-anchor="start" x="123" y="-356.8" font-size="9.00">q̂, dq̂/dt, q̇</text>
<text text-anchor="start" x="172" y="-356.8" baseline-shift="sub" font-size="9.00">o</text>
<text text-anchor="start" x="177" y="-356.8" font-size="9.00"> to the controller</text>
<text text-anchor="start" x="127.5" y="-347.8" font-size="9.00">q̈̂</text>
<text text-anchor="start" x="134.5" y="-347.8" baseline-shift="sub" font-size="9.00">r</text>
<text text-anchor="start" x="138.5" y="-347.8" font-size="9.00"> to the velocity observer</text>
</g></svg>"""


def test_the_label_checks_find_the_old_drawings_defects():
    """The checks of the block diagram's labels fail on what the generator drew before its
    labels were fixed: the double arrow's line through its own label, and texts that
    overlap (two labels at one place, two pieces of one line)."""
    crossed = _edges_through_labels(_OLD_DOUBLE_ARROW)
    assert {text for _, text in crossed} == {"q̂, dq̂/dt, q̇", " to the velocity observer"}
    assert len(_text_boxes(_OLD_DOUBLE_ARROW)) == 6
    # a label touching its edge at one end is graphviz's placement, not a crossing
    touching = _OLD_DOUBLE_ARROW.split("<text")[0] + (   # its right end 2 pt over the line
        '<text text-anchor="start" x="126.5" y="-356.8" font-size="9.00">q, q̇</text></g></svg>')
    assert not _edges_through_labels(touching)
    assert _edges_through_labels(touching, margin=0.0) == [("n1->n3", "q, q̇")]
    assert _overlapping([("a", "desired q", (0, 0, 40, 9)), ("b", "q̈̂ᵣ", (35, 5, 45, 14))])
    assert _overlapping([("e", "q̇", (0, 0, 10, 9)), ("e", "o", (8, 0, 14, 9))])


@pytest.mark.skipif(shutil.which("dot") is None, reason="graphviz's dot is not installed")
def test_paper_block_diagrams_labels_do_not_overlap():
    """The docs index's diagram: edge labels are one text element per line (graphviz places
    a ``<SUB>`` as a text element of its own, at its own font's widths, which a browser's
    wider font pushes over its neighbours), no two text boxes of the rendered SVG overlap,
    and no edge runs through a text, measured in a wider font
    (:func:`test_the_label_checks_find_the_old_drawings_defects`: the checks fail on the
    drawing before its labels were fixed)."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.results.block_diagram import paper_block_diagram
    from drake_coop.scenario import default_scenario

    dot = paper_block_diagram(build_experiment(plan_run(default_scenario()), log=True).diagram)
    assert "<SUB>" not in dot.split("fillcolor")[-1]       # edge labels: no separate pieces
    svg = subprocess.run(["dot", "-Tsvg"], input=dot, text=True, capture_output=True,
                         check=True).stdout
    boxes = _text_boxes(svg)
    assert len(boxes) > 40 and any("q̈̂ᵣ" in text for _, text, _ in boxes)
    assert not _overlapping(boxes)
    assert len(_edge_points(svg)) > 20
    assert not _edges_through_labels(svg)
