"""A readable block diagram of a Drake Diagram: only what is connected, left to right.

Drake's own picture (``System.GetGraphvizString``) draws every port of every subsystem; the
cooperative ``MultibodyPlant`` alone has some fifty, most of them unconnected, and its
``options`` only offer ``split="I/O"`` (one node for the inputs, one for the outputs), which
does not remove any. :func:`connected_graphviz` writes the DOT text itself from the Diagram's
connection map, so that the picture is decided by the connections and not by system names:

* a subsystem's input port is drawn if something feeds it (a connection or an exported input);
  an output port if it feeds a drawn subsystem or is exported;
* pure sinks (subsystems without any output port: loggers, visualizers) are left out and
  counted in the caption; ports that only fed them disappear with them;
* subsystems whose names share a prefix before the first ``_`` (``robot1_reference``,
  ``robot1_control``, ...) are grouped in a box named by the prefix;
* the layout runs left to right (``rankdir=LR``): sources, then the blocks they feed, so each
  robot's loop reads reference → control → plant → sensors, with the feedback drawn back.
"""

from __future__ import annotations

import html
from collections import Counter, defaultdict
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pydrake.systems.framework import Diagram, System

__all__ = ["connected_graphviz"]


def _is_sink(system: System) -> bool:
    return system.num_output_ports() == 0


def _exported(diagram: Diagram) -> tuple[list[tuple[str, System, int]], list[tuple[str, System,
                                                                                   int]]]:
    """Exported inputs ``(name, subsystem, port index)`` and outputs, found through the
    subsystems' port locators (``GetInputPortLocators`` / ``get_output_port_locator``)."""
    ins, outs = [], []
    for k in range(diagram.num_input_ports()):
        port = diagram.get_input_port(k)
        for system, index in diagram.GetInputPortLocators(port.get_index()):
            ins.append((port.get_name(), system, int(index)))
    for k in range(diagram.num_output_ports()):
        port = diagram.get_output_port(k)
        system, index = diagram.get_output_port_locator(port.get_index())
        outs.append((port.get_name(), system, int(index)))
    return ins, outs


def _node(endpoint: str) -> str:
    """The node of an edge end ``s3:y0:e`` or ``"in_q"``."""
    return endpoint if endpoint.startswith('"') else endpoint.split(":")[0]


def _distances_from_sources(edges: list[tuple[str, str]]) -> dict[str, float]:
    """Breadth-first distance of each node from the nodes nothing feeds (sources).

    An edge from a farther node to a nearer one closes a loop (the feedback of
    ``plant → encoders → control``); it is drawn without constraining the left-to-right
    ranks, so each loop reads forward from its source. Nodes only reachable through a cycle
    with no source are numbered after the rest, from the first one met.
    """
    succ: dict[str, list[str]] = defaultdict(list)
    nodes: list[str] = []
    fed: set[str] = set()
    for a, b in edges:
        u, v = _node(a), _node(b)
        succ[u].append(v)
        fed.add(v)
        for n in (u, v):
            if n not in nodes:
                nodes.append(n)
    dist: dict[str, float] = {}
    frontier = [n for n in nodes if n not in fed]
    while True:
        base = max(dist.values(), default=-1) + 1
        for n in frontier:
            dist[n] = base
        while frontier:
            nxt = []
            for u in frontier:
                for v in succ[u]:
                    if v not in dist:
                        dist[v] = dist[u] + 1
                        nxt.append(v)
            frontier = nxt
        rest = [n for n in nodes if n not in dist]
        if not rest:
            return defaultdict(float, dist)
        frontier = rest[:1]


def _label(system: System, ins: list[int], outs: list[int]) -> str:
    esc = html.escape
    rows = [f'<TR><TD COLSPAN="2" BGCOLOR="#e8eef7"><B>{esc(system.get_name())}</B><BR/>'
            f'<FONT POINT-SIZE="10">{esc(type(system).__name__)}</FONT></TD></TR>']
    for r in range(max(len(ins), len(outs), 1)):
        left = (f'<TD PORT="u{ins[r]}" ALIGN="LEFT">'
                f'{esc(system.get_input_port(ins[r]).get_name())}</TD>' if r < len(ins)
                else '<TD BORDER="0"></TD>')
        right = (f'<TD PORT="y{outs[r]}" ALIGN="RIGHT">'
                 f'{esc(system.get_output_port(outs[r]).get_name())}</TD>' if r < len(outs)
                 else '<TD BORDER="0"></TD>')
        rows.append(f"<TR>{left}{right}</TR>")
    return ('<<TABLE BORDER="0" CELLBORDER="1" CELLSPACING="0" CELLPADDING="3">'
            + "".join(rows) + "</TABLE>>")


def connected_graphviz(diagram: Diagram) -> str:
    """DOT text of ``diagram`` one level deep, drawing only connected ports.

    Parameters
    ----------
    diagram : pydrake.systems.framework.Diagram
        The built diagram.

    Returns
    -------
    str
        A ``digraph``; render with graphviz's ``dot``.
    """
    systems = [s for s in diagram.GetSystems() if not _is_sink(s)]
    drawn = {id(s) for s in systems}
    node = {id(s): f"s{k}" for k, s in enumerate(systems)}
    inputs: dict[int, set[int]] = defaultdict(set)
    outputs: dict[int, set[int]] = defaultdict(set)
    edges = []
    for (dst, i), (src, o) in diagram.connection_map().items():
        if id(dst) in drawn and id(src) in drawn:
            inputs[id(dst)].add(int(i))
            outputs[id(src)].add(int(o))
            edges.append((f"{node[id(src)]}:y{int(o)}:e", f"{node[id(dst)]}:u{int(i)}:w"))
    exported_in, exported_out = _exported(diagram)
    lines = []
    for name, system, i in exported_in:
        if id(system) in drawn:
            inputs[id(system)].add(i)
            lines.append(f'  "in_{name}" [shape=cds, style=filled, fillcolor="#dbe9ff", '
                         f'label="{html.escape(name)}"];')
            edges.append((f'"in_{name}"', f"{node[id(system)]}:u{i}:w"))
    for name, system, o in exported_out:
        if id(system) in drawn:
            outputs[id(system)].add(o)
            lines.append(f'  "out_{name}" [shape=cds, style=filled, fillcolor="#dcf5dc", '
                         f'label="{html.escape(name)}"];')
            edges.append((f"{node[id(system)]}:y{o}:e", f'"out_{name}"'))

    groups: dict[str, list[System]] = defaultdict(list)
    for s in systems:
        groups[s.get_name().split("_")[0]].append(s)
    for prefix, members in groups.items():
        in_cluster = 2 <= len(members) < len(systems)
        if in_cluster:
            lines.append(f'  subgraph "cluster_{prefix}" {{ label="{html.escape(prefix)}"; '
                         'style="rounded,dashed"; color="#8899aa";')
        for s in members:
            label = _label(s, sorted(inputs[id(s)]), sorted(outputs[id(s)]))
            lines.append(f"    {node[id(s)]} [shape=plaintext, label={label}];")
        if in_cluster:
            lines.append("  }")
    sinks = Counter(type(s).__name__ for s in diagram.GetSystems() if _is_sink(s))
    caption = html.escape(diagram.get_name())
    if sinks:
        caption += "\\n(not drawn: " + ", ".join(f"{n} {t}" for t, n in sorted(sinks.items())) \
            + ")"
    head = ["digraph {",
            "  rankdir=LR; newrank=true; nodesep=0.25; ranksep=0.6;",
            '  node [fontname="Helvetica", fontsize=12];',
            '  edge [arrowsize=0.7];',
            f'  labelloc=t; fontname="Helvetica"; label="{caption}";']
    rank = _distances_from_sources(edges)
    for side, prefix in (("source", '"in_'), ("sink", '"out_')):
        ends = sorted({_node(e) for edge in edges for e in edge if e.startswith(prefix)})
        if ends:
            lines.append(f"  {{ rank={side}; {'; '.join(ends)}; }}")
    body = [f"  {a} -> {b}" + (" [constraint=false];" if rank[_node(a)] > rank[_node(b)]
                                else ";") for a, b in edges]
    return "\n".join(head + lines + body + ["}"]) + "\n"
