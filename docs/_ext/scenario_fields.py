"""Generate the scenario reference (every field, its unit, range and default) from the code.

At ``builder-inited`` this writes ``docs/_generated/scenario_fields.md`` from

* the schema dataclasses (:mod:`drake_coop.scenario.schema`): field names, types, defaults and
  the ``Attributes`` section of each class's numpydoc docstring (the description);
* :data:`drake_coop.scenario.validation.BOUNDS` (unit and allowed range of every number) and
  :data:`~drake_coop.scenario.validation.LENGTHS` (fixed list lengths);
* the choices (``OBJECT_MODES``, ``VELOCITY_SOURCES``, ``FORCE_SOURCES``, ``ARM_MODELS``).

``docs/scenarios.md`` includes the generated file, so the page cannot drift from the code: a
field added to a dataclass appears with its bound, and a field without a description is a
build warning (fatal under ``-W``).
"""

from __future__ import annotations

import dataclasses
import re
import typing
from pathlib import Path

from sphinx.util import logging

logger = logging.getLogger(__name__)

_ROLE = re.compile(r":(\w+):`([^`]+)`")


def attribute_docs(cls: type) -> dict[str, str]:
    """``field -> description`` from the ``Attributes`` section of a numpydoc docstring.

    A heading line ``a, b : type`` documents every name it lists; the indented lines below it
    are the description (joined into one paragraph).
    """
    lines = (cls.__doc__ or "").expandtabs().splitlines()
    out: dict[str, str] = {}
    try:
        start = next(i for i, line in enumerate(lines)
                     if line.strip() == "Attributes" and set(lines[i + 1].strip()) == {"-"})
    except StopIteration:
        return out
    names: list[str] = []
    text: list[str] = []
    indent = None

    def flush() -> None:
        for name in names:
            out[name] = " ".join(text).strip()

    for line in lines[start + 2:]:
        if not line.strip():
            continue
        lead = len(line) - len(line.lstrip())
        if indent is None:
            indent = lead
        if lead < indent:
            break
        if lead == indent:
            if set(line.strip()) == {"-"}:      # the next section's underline
                break
            flush()
            head = line.strip().split(" : ")[0]
            names, text = [n.strip() for n in head.split(",")], []
        else:
            text.append(line.strip())
    flush()
    return out


def _markdown(text: str) -> str:
    text = text.replace("``", "`")
    text = _ROLE.sub(lambda m: "{" + m.group(1) + "}`" + m.group(2) + "`", text)
    return text.replace("|", "\\|")


def _type_name(t) -> str:
    origin = typing.get_origin(t)
    if origin is typing.Union:
        args = [a for a in typing.get_args(t) if a is not type(None)]
        return f"{_type_name(args[0])} or null"
    if origin is list:
        return f"list[{_type_name(typing.get_args(t)[0])}]"
    return getattr(t, "__name__", str(t))


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "required"
    if dataclasses.is_dataclass(value):
        return "see below"
    if value is None:
        return "null"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, str):
        return f"`{value}`" if value else "`\"\"`"
    if isinstance(value, list) and not value:
        return "`[]`"
    return f"`{value}`"


def _bound_text(bound) -> tuple[str, str]:
    if bound is None:
        return "", ""
    text = (f"{'(' if bound.lo_open else '['}{bound.lo:g}, {bound.hi:g}"
            f"{')' if bound.hi_open else ']'}")
    return bound.unit, text


def field_rows(cls: type, path: str, pattern: str, bounds: dict, lengths: dict,
               choices: dict[str, tuple[str, ...]], missing: list[str]) -> list[list[str]]:
    """One table row per field of ``cls`` (nested dataclasses get their own table)."""
    hints = typing.get_type_hints(cls)
    docs = attribute_docs(cls)
    rows = []
    for f in dataclasses.fields(cls):
        t = hints[f.name]
        pat = f"{pattern}.{f.name}" if pattern else f.name
        base = t
        args = [a for a in typing.get_args(t) if a is not type(None)]
        if typing.get_origin(t) is typing.Union and len(args) == 1:
            base = args[0]
        if dataclasses.is_dataclass(base) or (typing.get_origin(base) is list and
                                              dataclasses.is_dataclass(typing.get_args(base)[0])):
            continue                                   # documented in its own table
        bound = bounds.get(pat) or bounds.get(f"{pat}[]") or bounds.get(f"{pat}[][]")
        unit, allowed = _bound_text(bound)
        if f.name in choices:
            allowed = "one of " + ", ".join(f"`{c}`" for c in choices[f.name])
        if pat in lengths:
            allowed = (allowed + "; " if allowed else "") + f"{lengths[pat]} entries"
        if f"{pat}[]" in lengths:
            allowed = (allowed + "; " if allowed else "") + f"rows of {lengths[f'{pat}[]']}"
        if f.name not in docs:
            missing.append(f"{cls.__name__}.{f.name}")
        rows.append([f"`{path}{f.name}`", _type_name(t), _markdown(unit) or "—",
                     allowed or "—", _default(f), _markdown(docs.get(f.name, ""))])
    return rows


def sections():
    """(title, class, yaml prefix, bounds pattern) of every table, in reading order."""
    from drake_coop.scenario import schema as s
    return [
        ("Top level", s.Scenario, "", ""),
        ("`plant`", s.PlantSettings, "plant.", "plant"),
        ("`robots[i]`", s.Robot, "robots[i].", "robots[]"),
        ("`robots[i].gains`", s.Gains, "robots[i].gains.", "robots[].gains"),
        ("`robots[i].encoders`", s.Encoders, "robots[i].encoders.", "robots[].encoders"),
        ("`robots[i].force_sensor`", s.ForceSensorModel, "robots[i].force_sensor.",
         "robots[].force_sensor"),
        ("`robots[i].actuators`", s.Actuators, "robots[i].actuators.", "robots[].actuators"),
        ("`robots[i].model_error`", s.ModelError, "robots[i].model_error.",
         "robots[].model_error"),
        ("`task`", s.Task, "task.", "task"),
        ("`guards`", s.Guards, "guards.", "guards"),
        ("`object_model`", s.ObjectModelSettings, "object_model.", "object_model"),
    ]


def render() -> tuple[str, list[str]]:
    """The generated Markdown and the fields without a description."""
    from drake_coop.scenario import schema as s
    from drake_coop.scenario.validation import BOUNDS, LENGTHS, MAX_ROBOTS
    choices = {"object_mode": s.OBJECT_MODES, "velocity_source": s.VELOCITY_SOURCES,
               "force_source": s.FORCE_SOURCES, "mode": s.OBJECT_MODEL_MODES,
               "squeeze": s.SQUEEZE_SOURCES}
    missing: list[str] = []
    out = ["<!-- Generated by docs/_ext/scenario_fields.py at build time: do not edit. -->", ""]
    for title, cls, prefix, pattern in sections():
        out += [f"### {title}", ""]
        if cls is s.Scenario:
            out += [f"`robots` lists 2 to {MAX_ROBOTS} robots (`robots[i]` below).", ""]
        if cls is s.Robot:
            out += ["`model` is a shipped arm (" + ", ".join(f"`{a}`" for a in s.ARM_MODELS)
                    + ") or a `.urdf` path. Lists sized by the arm (`K_R`, torque limits, "
                    "friction: one per joint; `force_weights`: one per normal) are checked "
                    "once the model file is read.", ""]
        out += ["| field | type | unit | allowed | default | meaning |",
                "| --- | --- | --- | --- | --- | --- |"]
        for row in field_rows(cls, prefix, pattern, BOUNDS, LENGTHS, choices, missing):
            out.append("| " + " | ".join(row) + " |")
        out.append("")
    return "\n".join(out), missing


def _write(app) -> None:
    text, missing = render()
    for name in missing:
        logger.warning(f"scenario field {name} has no description in its class's Attributes")
    target = Path(app.srcdir) / "_generated" / "scenario_fields.md"
    target.parent.mkdir(exist_ok=True)
    if not target.exists() or target.read_text(encoding="utf-8") != text:
        target.write_text(text, encoding="utf-8")


def setup(app):
    app.connect("builder-inited", _write)
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
