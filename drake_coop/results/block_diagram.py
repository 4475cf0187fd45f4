"""The paper's block diagram, drawn from the built Drake Diagram.

Per robot: reference (28)–(29) → controller (13) ⇄ velocity observer (15)–(16) and force
observer (22) → actuators → the cooperative plant (1)–(2) → encoders → back to the controller
and observers. :func:`paper_block_diagram` writes it as graphviz DOT text from the Diagram
itself, so it stays true to what runs:

* nodes are the Diagram's subsystems, with each robot's control sub-diagram
  (``robotN_control``) opened into its parts, labelled by what they are (by their C++/Python
  type: :class:`~drake_coop.control.controller.Controller` reads "controller (13)") with the
  subsystem's name below;
* edges are the Diagram's connections, resolved through the control blocks' exported ports,
  one arrow per pair of blocks labelled with the signals it carries (``q``, ``τ``, ``q̂``, …);
* only what closes the loops is drawn: the subsystems from which a control block can be
  reached (references, encoders, the plant, actuators, a sensor model that feeds the
  controller); loggers, visualizers, the scene graph and the ground-truth force sensors that
  only feed the logs are left out;
* feedback (plant → encoders → observers) is drawn backwards (``dir=back``) so that each
  robot's loop reads left to right, reference → controller → actuators → plant, with the
  encoders under the actuators, as in the paper's figure.

The port-level picture for debugging (every connected port) is
:func:`drake_coop.results.graph.connected_graphviz`.
"""

from __future__ import annotations

import html
from collections import defaultdict
from typing import TYPE_CHECKING

from drake_coop.control.registry import SOURCES

if TYPE_CHECKING:
    from pydrake.systems.framework import Diagram, System

__all__ = ["BLOCK_LABELS", "SIGNAL_LABELS", "paper_block_diagram"]

#: What a subsystem is, by its type's name: (label, equation numbers or role, column).
#: Columns order each robot's loop left to right: 0 reference, 1 control, 2 actuators and
#: sensors, 3 the plant. The velocity and force sources' labels are their registry entries'
#: (:data:`drake_coop.control.registry.SOURCES`).
BLOCK_LABELS: dict[str, tuple[str, str, int]] = {
    "TrajectorySource": ("reference", "(28)–(29)", 0),
    "Controller": ("controller", "(13)", 1),
    **{s.class_name: (s.label, s.role, 1) for s in SOURCES},
    "Saturation": ("actuators", "saturation", 2),
    "CoulombFriction": ("joint friction", "unknown to (13)", 2),
    "Adder": ("+", "", 2),
    "Encoders": ("encoders", "q only", 2),
    "Demultiplexer": ("encoders", "q only, exact", 2),
    "FTSensor": ("F/T sensor model", "λ_s", 2),
    "ForceSensor": ("wrist force", "ground truth", 2),
    "WristKinematics": ("wrist kinematics", "", 3),
    "WristDynamics": ("wrist dynamics", "ground truth", 3),
    "ZeroOrderHold": ("hold", "", 2),
    "Multiplexer": ("signals", "", 2),
    "MultibodyPlant": ("cooperative plant", "(1)–(2): arms and object", 3),
}
#: Order of the blocks inside a robot's box (top to bottom within a column): the controller
#: beside its velocity estimate, the force estimate below, the actuators above the encoders.
_ORDER = ("TrajectorySource", "Controller",
          *(s.class_name for s in SOURCES if s.kind == "velocity"),
          *(s.class_name for s in SOURCES if s.kind == "force"),
          "Saturation", "CoulombFriction", "Adder", "Encoders", "Demultiplexer", "FTSensor", "ForceSensor")
#: Signals by output port name, as the paper writes them (HTML-like graphviz text). Indices
#: are Unicode subscripts, not ``<SUB>``: graphviz places a ``<SUB>`` as a text element of
#: its own at its own font's widths, and a browser drawing the SVG in a wider font printed it
#: over its neighbours (one text element per label cannot overlap itself).
SIGNAL_LABELS: dict[str, str] = {
    "q": "q", "tau": "τ",
    "qddot_r_hat": "q̈̂ᵣ", "q_hat": "q̂", "qdot_hat": "dq̂/dt",
    "qdot_o": "q̇ₒ", "lambda_hat": "λ̂", "Delta_F_tilde": "ΔF̃",
    "lambda_sensor": "λₛ", "lambda_meas": "λ", "F_meas": "F",
    "tau_ext_hat": "τ̂ₑₓₜ", "O_F_ext_hat": "F̂ₑₓₜ",
}
_SKIPPED_TYPES = {"SceneGraph"}


def _signal(source: System, port_name: str) -> str:
    """The signal an output port carries, as the paper writes it."""
    kind = type(source).__name__
    if kind == "TrajectorySource":
        return "desired q, q̇, q̈, λ"
    if kind in ("Saturation", "Adder"):
        return "τ"
    if kind == "MultibodyPlant" and not port_name.endswith("state"):
        return "reaction forces, body motion"
    if kind == "WristKinematics":
        return "wrist motion and forces"
    if port_name.endswith("state"):
        return "q, q̇"
    if kind == "Demultiplexer" and source.get_name().endswith("_encoders"):
        return "q"                          # ideal encoders: the plant's q, split off its state
    return SIGNAL_LABELS.get(port_name, html.escape(port_name))


def _is_control_block(system: System) -> bool:
    from pydrake.systems.framework import Diagram

    return isinstance(system, Diagram) and system.get_name().endswith("_control")


def _robot_of(name: str, robots: list[str]) -> str | None:
    return next((r for r in robots if name == r or name.startswith(f"{r}_")), None)


def _flatten(diagram: Diagram) -> tuple[list[System], list[tuple[System, System, str]]]:
    """Subsystems with the control blocks opened, and edges ``(source, target, signal)``."""
    systems: list[System] = []
    edges: list[tuple[System, System, str]] = []
    control = {id(s): s for s in diagram.GetSystems() if _is_control_block(s)}
    for s in diagram.GetSystems():
        if id(s) in control:
            systems += list(s.GetSystems())
            for (dst, _), (src, o) in s.connection_map().items():
                edges.append((src, dst, src.get_output_port(int(o)).get_name()))
        else:
            systems.append(s)
    for (dst, i), (src, o) in diagram.connection_map().items():
        if id(src) in control:
            block = control[id(src)]
            src, o = block.get_output_port_locator(block.get_output_port(int(o)).get_index())
        name = src.get_output_port(int(o)).get_name()
        targets = [dst]
        if id(dst) in control:
            block = control[id(dst)]
            targets = [t for t, _ in block.GetInputPortLocators(
                block.get_input_port(int(i)).get_index())]
        edges += [(src, t, name) for t in targets]
    return systems, edges


def paper_block_diagram(diagram: Diagram) -> str:
    """DOT text of the paper's block diagram of ``diagram`` (see the module docstring).

    Parameters
    ----------
    diagram : pydrake.systems.framework.Diagram
        The experiment's Diagram (:func:`~drake_coop.experiment.diagram.build_experiment`).

    Returns
    -------
    str
        A ``digraph``; render with graphviz's ``dot``.
    """
    robots = [s.get_name()[:-len("_control")] for s in diagram.GetSystems()
              if _is_control_block(s)]
    systems, edges = _flatten(diagram)
    # The connection maps' order varies from process to process, and graphviz's layout with
    # the edges' order: sorted, the drawing is the same on every run.
    edges.sort(key=lambda e: (e[0].get_name(), e[1].get_name(), e[2]))
    systems = [s for s in systems if type(s).__name__ not in _SKIPPED_TYPES]
    keep = {id(s) for s in systems}
    edges = [(a, b, n) for a, b, n in edges if id(a) in keep and id(b) in keep]
    # Keep what can reach a control block's part (backwards along the edges).
    into: dict[int, set[int]] = defaultdict(set)
    for a, b, _ in edges:
        into[id(b)].add(id(a))
    frontier = {id(s) for s in systems if _robot_of(s.get_name(), robots)
                and BLOCK_LABELS.get(type(s).__name__, ("", "", 0))[2] == 1}
    reach = set(frontier)
    while frontier:
        frontier = {u for v in frontier for u in into[v]} - reach
        reach |= frontier
    drawn = [s for s in systems if id(s) in reach]
    node = {id(s): f"n{k}" for k, s in enumerate(drawn)}
    column = {id(s): BLOCK_LABELS.get(type(s).__name__, ("", "", 2))[2] for s in drawn}

    def label(s: System) -> str:
        title, role, _ = BLOCK_LABELS.get(type(s).__name__, (s.get_name(), "", 2))
        rows = f"<B>{html.escape(title)}</B>"
        if role:
            rows += f"<BR/>{html.escape(role).replace('λ_d', 'λ<SUB>d</SUB>')}"
        rows += f'<BR/><FONT POINT-SIZE="8" COLOR="#667788">{html.escape(s.get_name())}</FONT>'
        return f"<{rows}>"

    fill = {0: "#eef6ee", 1: "#e8eef7", 2: "#f7f1e6", 3: "#f2f2f2"}
    lines = ["digraph {",
             "  rankdir=LR; newrank=true; nodesep=0.3; ranksep=0.55; compound=true;",
             '  node [shape=box, style="rounded,filled", fontname="Helvetica", fontsize=11];',
             '  edge [fontname="Helvetica", fontsize=9, arrowsize=0.7];',
             '  labelloc=t; fontname="Helvetica"; '
             'label="The paper\'s block diagram, per robot (equation numbers of the paper)";']
    by_robot: dict[str | None, list[System]] = defaultdict(list)
    for s in drawn:
        by_robot[_robot_of(s.get_name(), robots)].append(s)
    for robot, members in by_robot.items():
        members.sort(key=lambda s: _ORDER.index(type(s).__name__)
                     if type(s).__name__ in _ORDER else len(_ORDER))
        if robot is not None:
            lines.append(f'  subgraph "cluster_{robot}" {{ label="{html.escape(robot)}"; '
                         'style="rounded,dashed"; color="#8899aa";')
        for s in members:
            lines.append(f"    {node[id(s)]} [label={label(s)}, "
                         f'fillcolor="{fill[column[id(s)]]}"];')
        for c in range(4):
            same = [node[id(s)] for s in members if column[id(s)] == c]
            if len(same) > 1:
                lines.append(f"    {{ rank=same; {'; '.join(same)}; }}")
        if robot is not None:
            lines.append("  }")
    signals: dict[tuple[int, int], list[str]] = defaultdict(list)
    ends: dict[tuple[int, int], tuple[System, System]] = {}
    for a, b, name in edges:
        if id(a) in node and id(b) in node and a is not b:
            text = _signal(a, name)
            if text not in signals[(id(a), id(b))]:
                signals[(id(a), id(b))].append(text)
            ends[(id(a), id(b))] = (a, b)
    done = set()
    for key, texts in signals.items():
        if key in done:
            continue
        a, b = ends[key]
        text = ", ".join(texts)
        back = (key[1], key[0])
        if back in signals:
            # Both ways between two blocks (controller ⇄ velocity observer): one double arrow,
            # each direction's signals at the end it leaves (one label for both directions
            # sat mid-way on the curved edge, the line through its text).
            done.add(back)
            if type(a).__name__ == "Controller":
                a, b, text = b, a, ", ".join(signals[back])
            lines.append(f"  {node[id(a)]} -> {node[id(b)]} [dir=both, "
                         f"taillabel=<{text}>, headlabel=<{', '.join(signals[(id(b), id(a))])}>, "
                         "labeldistance=3, labelangle=30];")
        elif column[id(a)] > column[id(b)]:
            # Feedback: drawn from its target's side so the loop reads left to right.
            lines.append(f"  {node[id(b)]} -> {node[id(a)]} [dir=back, label=<{text}>];")
        elif type(a).__name__ == "TrajectorySource" and type(b).__name__ != "Controller":
            # The reference's other edges (to the force observer) do not pull it into line:
            # lined up between them, it put a label where the controller ⇄ velocity observer
            # arrow curves past.
            lines.append(f"  {node[id(a)]} -> {node[id(b)]} [label=<{text}>, weight=0];")
        else:
            lines.append(f"  {node[id(a)]} -> {node[id(b)]} [label=<{text}>];")
    lines.append("}")
    return "\n".join(lines) + "\n"

