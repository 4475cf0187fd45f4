"""Scenario fields named by dotted paths, as a study names them: resolving a path against the
scenario's schema and setting or reading the value at one.

A path names a scenario field with dots: ``control_period``, ``plant.time_step``,
``robots.0.gains.k_d``. A list index is a number; ``*`` matches every element
(``robots.*.gains.k_d``, ``robots.0.gains.K_R.*``).

Lists of numbers (``K_R``, ``base_xyz``) are set **as a whole or element-wise**:

* ``robots.0.gains.K_R: [[100, 100, 80]]`` (grid) sets the whole list;
* a single number at a list path (``robots.0.gains.K_R: [60, 120]``) sets every element to it;
* ``robots.0.gains.K_R.2`` or ``…K_R.*`` addresses elements.

A grid value that is a mapping at a path that names a mapping is a **variant**: it sets the
fields it lists and keeps the others, so fields that only make sense together vary together
(``robots.*: [{velocity_source: observer}, {velocity_source: difference,
difference_cutoff_hz: 20}]``).

In a grid, ``*`` gives every matched element the same value. In Monte Carlo, ``*`` draws
**independently** for every matched element (``robots.*.model_error.mass_scale`` gives each arm
its own draw); a path without ``*`` draws once: ``{scale_uniform: [lo, hi]}`` at a list path
multiplies the whole list by one factor, ``{uniform: …}`` sets every element to one draw.
"""

from __future__ import annotations

import copy
import types
import typing
from dataclasses import is_dataclass
from functools import lru_cache

from drake_coop.scenario.schema import Scenario
from drake_coop.studies.spec import StudyError

__all__ = ["get_value", "resolve", "set_value"]

#: One key of a path: a field's name or a list's index.
Key = str | int
#: A concrete key path (every ``*`` resolved).
KeyPath = tuple[Key, ...]


def _unwrap_optional(schema):
    """``X | None`` / ``Optional[X]`` -> ``X``."""
    if typing.get_origin(schema) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(schema) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return schema


@lru_cache(maxsize=None)
def _hints(cls) -> dict:
    return typing.get_type_hints(cls)


def resolve(data: dict, path: str, where: str) -> list[KeyPath]:
    """Concrete key paths matched by a dotted ``path`` in the scenario dict ``data``.

    Fields are checked against the :class:`~drake_coop.scenario.Scenario` dataclasses (a field
    missing from ``data`` but known to the schema is allowed: it will be created).

    Parameters
    ----------
    data : dict
        The scenario's untyped data.
    path : str
        A dotted path (``*`` for every element).
    where : str
        The study field naming it, for messages.

    Returns
    -------
    list of tuple
        The concrete key paths.

    Raises
    ------
    StudyError
        ``"<where>: no such field"`` (with the allowed names) or a bad index.
    """
    results: list[KeyPath] = []

    def walk(node, schema, parts: list[str], prefix: KeyPath) -> None:
        schema = _unwrap_optional(schema)
        if not parts:
            results.append(prefix)
            return
        head, rest = parts[0], parts[1:]
        shown = ".".join(map(str, prefix + (head,)))
        if is_dataclass(schema):
            hints = _hints(schema)
            if head not in hints:
                raise StudyError(f"{where}: no such field ({shown!r}); allowed here: "
                                 f"{', '.join(hints)}")
            child = node.get(head) if isinstance(node, dict) else None
            walk(child, hints[head], rest, prefix + (head,))
        elif typing.get_origin(schema) is list:
            (item,) = typing.get_args(schema)
            size = len(node) if isinstance(node, list) else 0
            if head == "*":
                if size == 0:
                    raise StudyError(f"{where}: {shown!r} matches nothing: the base scenario's "
                                     f"list {'.'.join(map(str, prefix))!r} is empty (give it "
                                     "its elements in the base scenario first)")
                indices = range(size)
            elif head.isdigit() and int(head) < size:
                indices = [int(head)]
            else:
                raise StudyError(f"{where}: {shown!r} is not an index of a list of {size} "
                                 f"(use 0 … {size - 1} or *)")
            for i in indices:
                walk(node[i], item, rest, prefix + (i,))
        else:
            raise StudyError(f"{where}: no such field ({shown!r}); "
                             f"{'.'.join(map(str, prefix))} is a value, not a mapping or list")

    walk(data, Scenario, path.split("."), ())
    return results


def get_value(data: dict, keys: KeyPath):
    """The value at a concrete key path (None when absent).

    Parameters
    ----------
    data : dict
        The scenario's untyped data.
    keys : tuple
        A concrete key path.

    Returns
    -------
    object
        The value, or None.
    """
    node = data
    for k in keys:
        if isinstance(k, int):
            node = node[k] if isinstance(node, list) and k < len(node) else None
        else:
            node = node.get(k) if isinstance(node, dict) else None
        if node is None:
            return None
    return node


def set_value(data: dict, keys: KeyPath, value) -> None:
    """Set the value at a concrete key path in place.

    A number at a list of numbers sets every element (broadcast); a mapping at a mapping
    updates the fields it names and keeps the others (a *variant*, see :func:`expand`).

    Parameters
    ----------
    data : dict
        The scenario's untyped data (changed in place).
    keys : tuple
        A concrete key path.
    value : object
        The value.
    """
    node = data
    for k in keys[:-1]:
        if isinstance(k, str) and (k not in node or node[k] is None):
            node[k] = {}
        node = node[k]
    last = keys[-1]
    old = node.get(last) if isinstance(node, dict) else node[last]
    if isinstance(value, dict) and isinstance(old, dict):
        for k, v in value.items():
            set_value(old, (k,), v)
        return
    if isinstance(old, list) and not isinstance(value, list):
        value = [value] * len(old)
    node[last] = copy.deepcopy(value)
