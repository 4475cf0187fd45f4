"""Every parameter of the public API is documented, and nothing else is (python-control's
``docstrings_test`` is the model).

The public API is what ``from drake_coop.<subpackage> import ...`` gives: each subpackage's
``__all__`` (a package inside one, ``control/object/``, included), the command line's
(``drake_coop.cli``, ``drake_coop.console``), and every module's public classes and functions
in the library, ``drake_coop.control`` (the layer a user's own diagram imports). For a function, its signature; for a class, its
constructor's (documented in the class docstring, numpydoc's convention, or the
``__init__``'s; a dataclass's or named tuple's fields in ``Parameters`` or ``Attributes``; a
class whose constructor is inherited from outside the package, an exception's, has nothing to
check). Its numpydoc ``Parameters`` section (``name : type`` lines, ``a, b : float`` for
several, ``*args``/``**kwargs`` by their names) must name each parameter (``self``/``cls``
aside) and no other; a callable without parameters needs no section. An unindented line inside
the section is read as a parameter, as numpydoc reads it (prose after the parameters belongs
in a ``Notes`` section).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "drake_coop"
#: Top-level modules of the command line.
TOP_LEVEL = ("cli", "console")
#: The library (``drake_coop.control``): every module's public names are its API.
LIBRARY = PKG / "control"

#: A numpydoc section header: a title line followed by a line of dashes.
_HEADER = re.compile(r"^\s*([A-Z][A-Za-z ]*)\n\s*-{3,}\s*$", re.M)


def _dunder_all(path: Path) -> list[str] | None:
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            if all(isinstance(e, ast.Constant) for e in node.value.elts):
                return [e.value for e in node.value.elts]
            # A computed __all__ (control's reads its sources' registry): the module says it.
            return list(importlib.import_module(_dotted(path)).__all__)
    return None


def _module_public(path: Path) -> list[str]:
    """Module-level public classes and functions of one source file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = [n.name for n in tree.body
             if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")]
    listed = _dunder_all(path)
    return names if listed is None else [n for n in names if n in listed]


def _dotted(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def public_api() -> list[tuple[str, str]]:
    """``(module, name)`` of every public class and function of the package's API."""
    out = []
    folders = [p.parent for p in PKG.glob("*/__init__.py") if p.parent.name != "data"]
    folders += [p.parent for f in list(folders) for p in f.glob("*/__init__.py")]
    for folder in sorted(folders):
        exported = _dunder_all(folder / "__init__.py") or []
        out += [(_dotted(folder), name) for name in exported]
        if folder == LIBRARY or LIBRARY in folder.parents:     # the library: every module
            for module in sorted(folder.glob("*.py")):
                if not module.name.startswith("_"):
                    out += [(_dotted(module), name) for name in _module_public(module)
                            if name not in exported]
    for module in TOP_LEVEL:
        if (PKG / f"{module}.py").exists():
            out += [(f"drake_coop.{module}", name)
                    for name in _module_public(PKG / f"{module}.py")]
    return sorted(set(out))


def documented_parameters(doc: str | None, sections=("Parameters",)) -> list[str] | None:
    """The names numpydoc sections (``Parameters`` by default) document, in order; None
    without such a section."""
    if not doc:
        return None
    doc = inspect.cleandoc(doc)
    headers = list(_HEADER.finditer(doc))
    names, found = [], False
    for i, header in enumerate(headers):
        if header.group(1).strip() not in sections:
            continue
        found = True
        end = headers[i + 1].start() if i + 1 < len(headers) else len(doc)
        for line in doc[header.end():end].splitlines():
            if not line.strip() or line[0].isspace():     # a description line
                continue
            head = line.split(" : ", 1)[0].rstrip(":").strip()
            names += [n.strip().lstrip("*") for n in head.split(",") if n.strip()]
    return names if found else None


def _is_record(cls) -> bool:
    """A dataclass or a named tuple: its constructor's parameters are its fields."""
    return dataclasses.is_dataclass(cls) or (issubclass(cls, tuple) and hasattr(cls, "_fields"))


def _signature_parameters(obj) -> list[str]:
    if inspect.isclass(obj):
        if _is_record(obj) and not dataclasses.is_dataclass(obj):
            return list(obj._fields)
        owner = next(c for c in obj.__mro__ if "__init__" in vars(c))
        if not inspect.isfunction(vars(owner)["__init__"]):
            return []          # a compiled constructor (an exception's, a binding's): not ours
        if owner.__module__.split(".")[0] in sys.stdlib_module_names:
            return []          # a constructor inherited from the standard library: its docs
        target = obj.__init__
    else:
        target = obj
    signature = inspect.signature(target)
    return [p.name for p in signature.parameters.values() if p.name not in ("self", "cls")]


def parameter_problems(obj, label: str) -> list[str]:
    """What ``obj``'s docstrings get wrong about its parameters (empty when nothing)."""
    parameters = _signature_parameters(obj)
    docs = [obj.__doc__]
    if inspect.isclass(obj) and "__init__" in vars(obj):
        docs.append(vars(obj)["__init__"].__doc__)
    kinds = ("Parameters", "Attributes") if inspect.isclass(obj) and _is_record(obj) \
        else ("Parameters",)
    sections = [s for s in (documented_parameters(d, kinds) for d in docs) if s is not None]
    documented = [n for s in sections for n in s]
    if not parameters and not documented:
        return []
    if not sections:
        return [f"{label}: no Parameters section (parameters {', '.join(parameters)})"]
    problems = [f"{label}: parameter {p!r} is not documented" for p in parameters
                if p not in documented]
    problems += [f"{label}: documents {n!r}, which it does not have" for n in documented
                 if n not in parameters]
    problems += [f"{label}: documents {n!r} twice" for n in sorted(set(documented))
                 if documented.count(n) > 1]
    return problems


def test_the_public_api_is_found():
    api = public_api()
    names = {name for _, name in api}
    # One of each kind the reader walks: a subpackage's export, a nested package's, the
    # command line's.
    assert {"AddCooperativeController", "Scenario", "grasp_matrix", "main", "error",
            "check_period"} <= names
    assert len(api) > 100


def public_callables() -> list[tuple[str, str]]:
    """:func:`public_api` without its data (``GRAVITY``, ``FORCE_SOURCES``, ...)."""
    return [(m, n) for m, n in public_api()
            if inspect.isclass(obj := getattr(importlib.import_module(m), n))
            or inspect.isfunction(obj)]


@pytest.mark.parametrize("module, name", public_callables())
def test_every_parameter_is_documented_and_nothing_else(module, name):
    obj = getattr(importlib.import_module(module), name)
    assert parameter_problems(obj, f"{module}.{name}") == []


# ------------------------------------------------------------- the check itself can fail

def _documented(a, b=1):
    """Something.

    Parameters
    ----------
    a : int
        A.
    b : int
        B.
    """


def _one_missing(a, b=1):
    """Something.

    Parameters
    ----------
    a : int
        A, with a colon: here.

    Returns
    -------
    c : int
        Not a parameter.
    """


def _one_extra(a):
    """Something.

    Parameters
    ----------
    a, b : int
        A and B.
    """


def _no_section(a):
    """Something about ``a``."""


class _Class:
    """A class.

    Parameters
    ----------
    x : float
        X.
    *args
        More.
    """

    def __init__(self, x, *args, y=0):
        pass


@pytest.mark.parametrize("obj, problems", [
    (_documented, []),
    (_one_missing, ["f: parameter 'b' is not documented"]),
    (_one_extra, ["f: documents 'b', which it does not have"]),
    (_no_section, ["f: no Parameters section (parameters a)"]),
    (_Class, ["f: parameter 'y' is not documented"]),
    (lambda: None, []),
])
def test_a_wrong_docstring_is_reported(obj, problems):
    assert parameter_problems(obj, "f") == problems


@dataclasses.dataclass
class _Record:
    """A record.

    Attributes
    ----------
    x : float
        X.
    """

    x: float
    y: float = 0.0


class _Error(ValueError):
    """An exception with the constructor of its base."""


def _prose_after(a):
    """Something.

    Parameters
    ----------
    a : int
        A.

    A paragraph after the parameters.
    """


@pytest.mark.parametrize("obj, problems", [
    (_Record, ["f: parameter 'y' is not documented"]),
    (_Error, []),
    (_prose_after, ["f: documents 'A paragraph after the parameters.', which it does not have"]),
])
def test_records_exceptions_and_stray_prose(obj, problems):
    assert parameter_problems(obj, "f") == problems
