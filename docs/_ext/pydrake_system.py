"""Render pydrake's ``.. pydrake_system::`` docstring blocks as a port table.

Drake's own documentation draws a LeafSystem's ports from a YAML-like block::

    .. pydrake_system::

        name: Controller
        input_ports:
        - q
        - reference
        output_ports:
        - tau

This directive reads that block (``name``, ``input_ports``, ``output_ports``; list items as
``- name`` lines or as ``[a, b]``) and renders it as a three-column table: inputs, the
system's name, outputs. Anything it cannot read is a Sphinx warning naming the line, so a
malformed block fails a ``-W`` build.

The docstrings describe each port in numpydoc-style ``Input ports`` / ``Output ports``
sections, which numpydoc does not know and drops (with a Python warning, not a Sphinx one).
:func:`move_port_sections` turns them into rubrics with definition lists placed before the
first numpydoc section, before numpydoc reads the docstring.
"""

from __future__ import annotations

import re

from docutils import nodes
from docutils.parsers.rst import Directive
from sphinx.util import logging

_KEYS = ("name", "input_ports", "output_ports")
logger = logging.getLogger(__name__)


def parse_block(lines: list[str]) -> dict[str, object]:
    """The block's ``name`` (str) and port lists, or ValueError naming the first bad line."""
    out: dict[str, object] = {"name": "", "input_ports": [], "output_ports": []}
    key = None
    for raw in lines:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("- "):
            if key not in ("input_ports", "output_ports"):
                raise ValueError(f"list item outside input_ports/output_ports: {raw!r}")
            out[key].append(line[2:].strip())
            continue
        head, sep, rest = line.partition(":")
        if not sep or head.strip() not in _KEYS:
            raise ValueError(f"expected one of {', '.join(_KEYS)}: {raw!r}")
        key, rest = head.strip(), rest.strip()
        if key == "name":
            out["name"] = rest
        elif rest:
            if not (rest.startswith("[") and rest.endswith("]")):
                raise ValueError(f"{key}: expected a list, got {rest!r}")
            out[key] = [p.strip() for p in rest[1:-1].split(",") if p.strip()]
    if not out["name"]:
        raise ValueError("the block has no name")
    return out


class PydrakeSystem(Directive):
    """``.. pydrake_system::`` → a table of the system's input and output ports."""

    has_content = True

    def run(self) -> list[nodes.Node]:
        try:
            block = parse_block(list(self.content))
        except ValueError as e:
            return [self.state_machine.reporter.warning(
                f"pydrake_system: {e}", line=self.lineno)]
        inputs, outputs = block["input_ports"], block["output_ports"]
        rows = max(len(inputs), len(outputs), 1)
        table = nodes.table(classes=["pydrake-system"])
        group = nodes.tgroup(cols=3)
        table += group
        for width in (2, 2, 2):
            group += nodes.colspec(colwidth=width)
        head = nodes.thead()
        group += head
        head += self._row(["input ports", "system", "output ports"], header=True)
        body = nodes.tbody()
        group += body
        for i in range(rows):
            body += self._row([inputs[i] if i < len(inputs) else "",
                               block["name"] if i == 0 else "",
                               outputs[i] if i < len(outputs) else ""])
        return [table]

    @staticmethod
    def _row(cells: list[str], header: bool = False) -> nodes.row:
        row = nodes.row()
        for text in cells:
            entry = nodes.entry()
            if text:
                para = nodes.paragraph()
                para += nodes.strong(text=text) if header else nodes.literal(text=text)
                entry += para
            row += entry
        return row


_PORT_HEADER = re.compile(r"^(Input|Output) ports\b")
_TERM = re.compile(r"^(\S+?)(\s+:\s+.*)?$")


def _is_header(lines: list[str], i: int) -> bool:
    """``lines[i]`` is a numpydoc section title (an unindented line underlined by dashes)."""
    return (i + 1 < len(lines) and lines[i].strip() != "" and not lines[i].startswith(" ")
            and set(lines[i + 1].strip()) == {"-"})


def move_port_sections(lines: list[str]) -> list[str]:
    """The docstring's lines with its ``Input ports ...`` / ``Output ports ...`` sections
    moved before its first numpydoc section, each as a rubric (its title) and a definition
    list (``name : type`` then the indented description, the name set as code)."""
    moved: list[str] = []
    kept: list[str] = []
    i = 0
    while i < len(lines):
        if _is_header(lines, i) and _PORT_HEADER.match(lines[i]):
            moved += [f".. rubric:: {lines[i].strip()}", ""]
            i += 2
            while i < len(lines) and not _is_header(lines, i):
                line = lines[i]
                term = _TERM.match(line) if line and not line.startswith(" ") else None
                if term:
                    line = f"``{term.group(1)}``{term.group(2) or ''}"
                    if moved[-1] != "":      # a port without a description ends its item
                        moved.append("")
                moved.append(line)
                i += 1
            moved.append("")
        else:
            kept.append(lines[i])
            i += 1
    if not moved:
        return lines
    first = next((j for j in range(len(kept)) if _is_header(kept, j)), len(kept))
    return kept[:first] + moved + kept[first:]


def _process_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    lines[:] = move_port_sections(lines)


def setup(app):
    import warnings

    # numpydoc parses each docstring a second time, unprocessed, for the signature, and warns
    # (a Python warning, which -W does not turn into an error) about the port sections that
    # _process_docstring has already moved into rubrics for the rendered page: silence only
    # those, so that any other numpydoc warning still shows in the build's output.
    warnings.filterwarnings("ignore", message=r"Unknown section (Input|Output) Ports",
                            category=UserWarning, module=r"numpydoc\.docscrape")
    app.add_directive("pydrake_system", PydrakeSystem)
    # Before numpydoc's own handler (priority 500), which would drop the port sections.
    app.connect("autodoc-process-docstring", _process_docstring, priority=400)
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
