"""Allowed ranges of numbers in nested dataclasses, checked field by field.

A table maps a *dotted field pattern* to a :class:`Bound`::

    {"control_period": Bound(1e-4, 0.1, "s"),
     "robots[].gains.K_R[]": Bound(0, 1e4, "N·m·s/rad", lo_open=True)}

``[]`` stands for any list index. :func:`check_numbers` walks a dataclass instance (nested
dataclasses, lists of them) and for every number field (``float`` or ``int``, ``X | None`` when
set, lists of them) checks that it is a finite number, inside its bound when the table has one,
and that a list has the length of the ``lengths`` table. The first
problem raises the given error class with one line naming the concrete field
(``robots[1].gains.K_R[2]``), the allowed range with its unit, and the value (cut short).

:func:`show` and :func:`one_line` keep every message echoing user input short and on one line.
"""

from __future__ import annotations

import dataclasses
import math
import reprlib
import typing
from dataclasses import dataclass
from functools import lru_cache

__all__ = ["Bound", "check_numbers", "numeric_fields", "one_line", "optional_of", "show"]

#: Longest message of a user-facing error (characters).
MAX_MESSAGE = 300

_repr = reprlib.Repr()
_repr.maxlevel, _repr.maxlist, _repr.maxdict, _repr.maxstring, _repr.maxother = 2, 4, 4, 40, 40


def show(value: object, limit: int = 60) -> str:
    """A short one-line rendering of a user-given value (YAML spelling for null/booleans).

    Parameters
    ----------
    value : object
        The value.
    limit : int
        The longest rendering, characters.
    """
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and abs(value) > 10 ** 18:
        return f"an integer of {len(str(abs(value)))} digits"
    try:
        text = _repr.repr(value)
    except (ValueError, RecursionError):
        text = f"a {type(value).__name__}"
    return one_line(text, limit)


def one_line(text: object, limit: int = MAX_MESSAGE) -> str:
    """``text`` on one line (whitespace runs collapsed), cut to ``limit`` characters.

    Parameters
    ----------
    text : object
        The text (its ``str``).
    limit : int
        The longest result, characters.
    """
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 1] + "…"


@dataclass(frozen=True)
class Bound:
    """A closed or half-open interval ``[lo, hi]`` with its unit.

    Attributes
    ----------
    lo, hi : float
        The ends, in ``unit``.
    unit : str
        The unit, for messages.
    lo_open, hi_open : bool
        Whether an end is excluded.
    """

    lo: float
    hi: float
    unit: str = ""
    lo_open: bool = False
    hi_open: bool = False

    def __contains__(self, value: float) -> bool:
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        return above and below

    def __str__(self) -> str:
        text = (f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
                f"{')' if self.hi_open else ']'}")
        return f"{text} {self.unit}".rstrip()


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_number(value: object, name: str, pattern: str, bounds: dict[str, Bound],
                  error: type[Exception], integer: bool = False) -> None:
    bound = bounds.get(pattern)
    kind = "an integer" if integer else "a finite number"
    allowed = f"{kind} in {bound}" if bound else kind
    if not _is_number(value) or (integer and not isinstance(value, int)):
        raise error(f"{name} must be {allowed}, got {show(value)}")
    try:
        finite = math.isfinite(value)
    except OverflowError:              # an int too large for a float
        finite = False
    if not finite or (bound is not None and value not in bound):
        raise error(f"{name} must be {allowed}, got {show(value)}")


def check_numbers(obj: object, bounds: dict[str, Bound], lengths: dict[str, int], *,
                  error: type[Exception] = ValueError, path: str = "", pattern: str = ""
                  ) -> None:
    """Check every number field of a dataclass tree (see the module's docstring).

    Parameters
    ----------
    obj : dataclass instance
        The tree (nested dataclasses and lists of them).
    bounds : dict
        ``pattern -> Bound`` (``[]`` for any index, e.g. ``robots[].home[]``).
    lengths : dict
        ``pattern -> length`` of list fields.
    error : type
        Exception raised with the one-line message.
    path : str
        The tree's path for messages (``""`` at the root).
    pattern : str
        The tree's bounds pattern (``""`` at the root).

    Raises
    ------
    error
        The first field that is not a finite number, out of its bound or of the wrong length.
    """
    hints = _type_hints(type(obj))
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        name = f"{path}.{f.name}" if path else f.name
        pat = f"{pattern}.{f.name}" if pattern else f.name
        schema = optional_of(hints[f.name])
        if value is None and schema is not hints[f.name]:
            continue                                # an optional field left unset
        if schema in (float, int):
            _check_number(value, name, pat, bounds, error, integer=schema is int)
        elif typing.get_origin(schema) is list:
            (item,) = typing.get_args(schema)
            if pat in lengths and len(value) != lengths[pat]:
                raise error(f"{name} must have {lengths[pat]} entries, got {len(value)}")
            for i, v in enumerate(value):
                if item in (float, int):
                    _check_number(v, f"{name}[{i}]", f"{pat}[]", bounds, error,
                                  integer=item is int)
                elif typing.get_origin(item) is list:     # a matrix: list of rows
                    row_pat = f"{pat}[]"
                    if row_pat in lengths and len(v) != lengths[row_pat]:
                        raise error(f"{name}[{i}] must have {lengths[row_pat]} entries, "
                                    f"got {len(v)}")
                    for j, x in enumerate(v):
                        _check_number(x, f"{name}[{i}][{j}]", f"{row_pat}[]", bounds, error)
                elif dataclasses.is_dataclass(item):
                    check_numbers(v, bounds, lengths, error=error, path=f"{name}[{i}]",
                                  pattern=f"{pat}[]")
        elif dataclasses.is_dataclass(schema) and value is not None:
            check_numbers(value, bounds, lengths, error=error, path=name, pattern=pat)


def optional_of(schema):
    """``X`` for ``X | None`` (``Optional[X]``), else ``schema`` itself.

    Parameters
    ----------
    schema : type
        A type hint.
    """
    args = typing.get_args(schema)
    if type(None) in args and len(args) == 2:
        return next(a for a in args if a is not type(None))
    return schema


def numeric_fields(schema: type, pattern: str = "") -> list[str]:
    """The patterns of every number (``float``, ``int``, optional or in lists) of a dataclass
    schema: the keys its bounds table should have.

    Parameters
    ----------
    schema : type
        The dataclass.
    pattern : str
        The prefix of its patterns.
    """
    out = []
    hints = _type_hints(schema)
    for f in dataclasses.fields(schema):
        pat = f"{pattern}.{f.name}" if pattern else f.name
        t = optional_of(hints[f.name])
        if t in (float, int):
            out.append(pat)
        elif typing.get_origin(t) is list:
            (item,) = typing.get_args(t)
            if item in (float, int):
                out.append(f"{pat}[]")
            elif typing.get_origin(item) is list:
                out.append(f"{pat}[][]")
            elif dataclasses.is_dataclass(item):
                out += numeric_fields(item, f"{pat}[]")
        elif dataclasses.is_dataclass(t):
            out += numeric_fields(t, pat)
    return out


@lru_cache(maxsize=None)
def _type_hints(cls) -> dict:
    """``typing.get_type_hints`` of a dataclass, once per class (a study validates thousands
    of scenarios)."""
    return typing.get_type_hints(cls)
