"""Every public callable of the package is documented, every parameter of it, and nothing else
(python-control's ``docstrings_test`` is the model).

Public is what a reader can reach without an underscore: every module of ``drake_coop`` whose
dotted name has no part starting with ``_`` (``__main__`` modules are private; a package's
``__init__`` is the package), and in it every class and function defined at module level whose
name does not start with ``_``, and every method of such a class whose name does not (static,
class methods and properties included). Each subpackage's ``__all__`` (a package inside one,
``control/object/``, included) is checked too, whatever module its names come from.

Each public callable has a docstring with a summary line. For a function or a method, its
signature; for a class, its constructor's (documented in the class docstring, numpydoc's
convention, or the ``__init__``'s; a dataclass's or named tuple's fields in ``Parameters`` or
``Attributes``; a class whose constructor is inherited from outside the package, an
exception's, has nothing to check). Its numpydoc ``Parameters`` section (``name : type``
lines, ``a, b : float`` for several, ``*args``/``**kwargs`` by their names) must name each
parameter (``self``/``cls`` aside) and no other; a callable without parameters needs no
section. An unindented line inside the section is read as a parameter, as numpydoc reads it
(prose after the parameters belongs in a ``Notes`` section). Every entry of the
``Parameters``, ``Attributes``, ``Returns`` and ``Yields`` sections has a description (an
indented line under it: what it means, with its unit). A generator has a ``Yields``
section. A function or method that returns a value (a ``return`` with a value in its own
body, or a return annotation other than ``None``) has a ``Returns`` section *unless its
summary names the value* — python-control's rule, a ``Returns`` only where it tells
something: the summary (its first paragraph) reads as the description of what is returned,
which is the case when it begins with a determiner (``The``, ``A``, ``An``, ``Its``,
``Their``, ``Each``, ``Every``, ``One``), with ``Whether``, ``True``, ``What``, ``Where``,
``Which``, ``Return(s)``, with a number, or with a formula (a code span, ``:math:``, or a
symbol such as ``ρ``, ``Φ``, ``λ``) — not with a verb (``Write``, ``Build``, ``Check``: what
the function does, after which the value still needs its line). A property needs its
docstring only (it describes the value). And a ``Returns`` entry says more than its type:
at most :data:`THIN_RETURNS_MAX` of the package's entries have a description of three
words or fewer (``The path.``), where the summary then should carry the value instead.

Two rules exempt a method, and no list of names does:

- an *override*: a method whose name a base class already defines (Drake's
  ``LeafSystem.DoCalcTimeDerivatives``, ``DoPublish``, a package base's method, which is
  checked where it is defined) is documented by its base;
- a *port getter* of a Drake system, ``get_<port>_input_port()`` or
  ``get_<port>_output_port()`` without parameters, is documented by its own docstring (no
  ``Returns`` section: the port) or else by its class's ``.. pydrake_system::`` block, which
  must name the port (checked).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "drake_coop"

#: A numpydoc section header: a title line followed by a line of dashes.
_HEADER = re.compile(r"^\s*([A-Z][A-Za-z ]*)\n\s*-{3,}\s*$", re.M)
#: A Drake system's port getter (documented by its class's ``.. pydrake_system::`` block).
_PORT_GETTER = re.compile(r"^get_(\w+)_(?:input|output)_port$")
#: A summary that names the returned value (the module's rule): a determiner, a question
#: word, a number or a formula first, not a verb.
_NAMES_THE_VALUE = re.compile(r"^(?:(?:The|A|An|Its|Their|Each|Every|One|Whether|True|What|"
                              r"Where|Which|Return|Returns)\b|``|:math:|\d|[^\x00-\x7f])")
#: The largest share of the package's ``Returns`` entries whose description has three words
#: or fewer (a type restated: ``The path.``).
THIN_RETURNS_MAX = 0.15


def summary_names_the_value(doc: str | None) -> bool:
    """Whether ``doc``'s summary names the value a function returns (the module's rule)."""
    return bool(doc) and bool(_NAMES_THE_VALUE.match(inspect.cleandoc(doc).lstrip()))


def _dunder_all(path: Path) -> list[str] | None:
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            if all(isinstance(e, ast.Constant) for e in node.value.elts):
                return [e.value for e in node.value.elts]
            # A computed __all__ (control's reads its sources' registry): the module says it.
            return list(importlib.import_module(_dotted(path)).__all__)
    return None


def _dotted(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _source(module: str) -> Path:
    """The source file of a dotted module name."""
    path = ROOT.joinpath(*module.split("."))
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


def public_modules() -> list[Path]:
    """The source file of every public module: no part of its dotted name starts with ``_``."""
    return [p for p in sorted(PKG.rglob("*.py"))
            if not any(part.startswith("_") for part in _dotted(p).split("."))]


_DEFINITION = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)


def _definitions(path: Path) -> dict[str, ast.AST]:
    """Qualified name -> node of a module's public module-level definitions and of the public
    methods of its public classes."""
    out = {}
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, _DEFINITION) and not node.name.startswith("_"):
            out[node.name] = node
            if isinstance(node, ast.ClassDef):
                for m in node.body:      # a property's setter keeps its getter's node
                    if isinstance(m, _DEFINITION[:2]) and not m.name.startswith("_"):
                        out.setdefault(f"{node.name}.{m.name}", m)
    return out


def public_api() -> list[tuple[str, str]]:
    """``(module, name)`` of every public class and function of the package: the
    subpackages' exports and every public module's own definitions."""
    out = []
    for folder in sorted(p.parent for p in PKG.rglob("__init__.py")):
        out += [(_dotted(folder), name) for name in _dunder_all(folder / "__init__.py") or []]
    for module in public_modules():
        out += [(_dotted(module), name) for name in _definitions(module) if "." not in name]
    return sorted(set(out))


def public_methods() -> list[tuple[str, str]]:
    """``(module, Class.method)`` of every public method of a public class."""
    return sorted((_dotted(module), name) for module in public_modules()
                  for name in _definitions(module) if "." in name)


def exemption(cls: type, name: str) -> str | None:
    """Why method ``name`` of ``cls`` is documented elsewhere (the module's two rules), or
    None."""
    if any(name in vars(base) for base in cls.__mro__[1:]):
        return "override"
    if _PORT_GETTER.match(name) and not _signature_parameters(getattr(cls, name)):
        return "port getter"
    return None


def _system_ports(doc: str | None) -> set[str]:
    """The port names of a ``.. pydrake_system::`` block."""
    match = re.search(r"\.\. pydrake_system::\n((?:[ \t]*\n|[ \t]+\S.*\n)+)", doc or "")
    return set(re.findall(r"^\s*-\s*(\S+)\s*$", match.group(1), re.M)) if match else set()


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


def undescribed_entries(doc: str | None) -> list[str]:
    """The entries (``name : type`` lines, or a bare type under ``Returns``) of ``doc``'s
    ``Parameters``, ``Attributes``, ``Returns`` and ``Yields`` sections with no description
    under them: each parameter, field and result says what it means (and its unit)."""
    if not doc:
        return []
    doc = inspect.cleandoc(doc)
    headers = list(_HEADER.finditer(doc))
    out = []
    for i, header in enumerate(headers):
        if header.group(1).strip() not in ("Parameters", "Attributes", "Returns", "Yields"):
            continue
        end = headers[i + 1].start() if i + 1 < len(headers) else len(doc)
        lines = doc[header.end():end].strip("\n").splitlines()
        for j, line in enumerate(lines):
            following = lines[j + 1] if j + 1 < len(lines) else ""
            if line.strip() and not line[0].isspace() and not following[:1].isspace():
                out.append(line.strip())
    return out


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


def _return_kind(node: ast.AST) -> str | None:
    """``"Yields"`` for a generator, ``"Returns"`` for a function that returns a value (a
    ``return`` with a value in its own body, or a return annotation other than ``None``), else
    None."""
    kind, stack = None, list(node.body)
    while stack:
        n = stack.pop()
        if isinstance(n, (*_DEFINITION, ast.Lambda)):
            continue                  # a nested function's returns are not this one's
        if isinstance(n, (ast.Yield, ast.YieldFrom)):
            return "Yields"
        if isinstance(n, ast.Return) and n.value is not None and not (
                isinstance(n.value, ast.Constant) and n.value.value is None):
            kind = "Returns"
        stack.extend(ast.iter_child_nodes(n))
    annotation = node.returns
    if annotation is not None and not (
            isinstance(annotation, ast.Constant) and annotation.value in (None, "None")) \
            and not (isinstance(annotation, ast.Name) and annotation.id in ("NoReturn", "Never")):
        kind = "Returns"
    return kind


def member_problems(owner, name: str, node: ast.AST, label: str) -> list[str]:
    """What the docstring of ``owner``'s member ``name`` (a module's class or function, a
    class's method; ``node`` its definition) gets wrong: no summary, its parameters, no
    ``Returns``/``Yields``; nothing for an exempt method (the module's two rules)."""
    obj = inspect.getattr_static(owner, name)
    if inspect.isclass(owner):
        reason = exemption(owner, name)
        if reason == "override":
            return []
        if reason == "port getter":
            port = _PORT_GETTER.match(name).group(1)
            documented = ast.get_docstring(node) or port in _system_ports(owner.__doc__)
            return [] if documented else [
                f"{label}: a port getter without a docstring whose port {port!r} its class's "
                "pydrake_system block does not name"]
    doc = ast.get_docstring(node)
    if not doc or not doc.strip():
        return [f"{label}: no docstring"]
    if not inspect.isclass(obj) and not isinstance(obj, (staticmethod, classmethod)) \
            and not inspect.isfunction(obj):
        return []                     # a property: its docstring describes the value
    target = obj if inspect.isclass(obj) else getattr(obj, "__func__", obj)
    problems = parameter_problems(target, label)
    docs = [doc] + ([ast.get_docstring(m) or "" for m in node.body
                     if isinstance(m, ast.FunctionDef) and m.name == "__init__"]
                    if isinstance(node, ast.ClassDef) else [])
    problems += [f"{label}: {entry!r} has no description" for d in docs
                 for entry in undescribed_entries(d)]
    kind = None if inspect.isclass(obj) else _return_kind(node)
    if kind == "Returns" and summary_names_the_value(doc):
        kind = None                   # the summary is the value's description
    if kind and documented_parameters(doc, (kind,)) is None:
        problems.append(f"{label}: {kind.lower()} a value but has no {kind} section")
    return problems


def definition_problems(module: str, qualname: str) -> list[str]:
    """:func:`member_problems` of one public definition, ``Class.method`` or a module's
    ``name``."""
    node = _definitions(_source(module))[qualname]
    owner = importlib.import_module(module)
    *path, name = qualname.split(".")
    for part in path:
        owner = getattr(owner, part)
    return member_problems(owner, name, node, f"{module}.{qualname}")


def test_the_public_api_is_found():
    api = public_api()
    names = {name for _, name in api}
    # One of each kind the reader walks: a subpackage's export, a nested package's, the
    # command line's.
    assert {"AddCooperativeController", "Scenario", "grasp_matrix", "main", "error",
            "check_period"} <= names
    assert len(api) > 400
    methods = {name for _, name in public_methods()}
    assert {"VelocitySource.get_q_input_port", "Arm.J_phi", "CoopPlant.set_held"} <= methods
    assert not any(name.split(".")[-1].startswith("_") for name in methods)
    modules = {_dotted(p) for p in public_modules()}
    assert {"drake_coop.cli.run", "drake_coop.control.object", "drake_coop"} <= modules
    assert not any("__main__" in m for m in modules)


def public_callables() -> list[tuple[str, str]]:
    """:func:`public_api` without its data (``GRAVITY``, ``FORCE_SOURCES``, ...)."""
    return [(m, n) for m, n in public_api()
            if inspect.isclass(obj := getattr(importlib.import_module(m), n))
            or inspect.isfunction(obj)]


@pytest.mark.parametrize("module, name", public_callables())
def test_every_parameter_is_documented_and_nothing_else(module, name):
    obj = getattr(importlib.import_module(module), name)
    assert parameter_problems(obj, f"{module}.{name}") == []


@pytest.mark.parametrize("module, name", sorted(set(public_methods()) | {
    (m, n) for m, n in public_callables() if n in _definitions(_source(m))}))
def test_every_public_definition_has_a_summary_its_parameters_and_its_returns(module, name):
    assert definition_problems(module, name) == []


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



# ------------------------------------------------- summaries, returns and the two exemptions

def _node(obj) -> ast.AST:
    return ast.parse(textwrap.dedent(inspect.getsource(obj))).body[0]


def _returns(a):
    """Something.

    Parameters
    ----------
    a : int
        A.
    """
    return a


def _returns_in_a_nested_function_only(a) -> None:
    """Something.

    Parameters
    ----------
    a : int
        A.
    """
    def inner():
        return a
    inner()


def _annotated(a) -> int:
    """Something.

    Parameters
    ----------
    a : int
        A.
    """
    raise ValueError(a)


def _generator(a):
    """Something.

    Parameters
    ----------
    a : int
        A.

    Returns
    -------
    int
        Not what a generator documents.
    """
    yield a


def _no_docstring():
    return None


def _undescribed(a, b):
    """Something.

    Parameters
    ----------
    a : int
    b : int
        B.

    Returns
    -------
    int
    """
    return a + b


@pytest.mark.parametrize("obj, problems", [
    (_returns, ["f: returns a value but has no Returns section"]),
    (_returns_in_a_nested_function_only, []),
    (_annotated, ["f: returns a value but has no Returns section"]),
    (_generator, ["f: yields a value but has no Yields section"]),
    (_no_docstring, ["f: no docstring"]),
    (_one_missing, ["f: parameter 'b' is not documented"]),
    (_undescribed, ["f: 'a : int' has no description", "f: 'int' has no description"]),
])
def test_a_function_without_summary_returns_or_yields_is_reported(obj, problems):
    assert member_problems(sys.modules[__name__], obj.__name__, _node(obj), "f") == problems


class _Base:
    def shared(self, x):
        """The base's documentation.

        Parameters
        ----------
        x : int
            X.
        """


class _System(_Base):
    """A system.

    .. pydrake_system::

        name: System
        input_ports:
        - q
        output_ports:
        - tau
    """

    def shared(self, x):
        return x

    def get_q_input_port(self):
        return None

    def get_lambda_input_port(self):
        return None

    def get_tau_output_port(self):
        """The torque."""

    def get_gain_output_port(self, i):
        """A getter with a parameter is a method like any other."""

    @property
    def value(self):
        """A property: its docstring describes the value."""
        return 1

    @property
    def silent(self):
        return 1


@pytest.mark.parametrize("name, problems", [
    ("shared", []),                               # an override: its base documents it
    ("get_q_input_port", []),                     # its port is in the block
    ("get_lambda_input_port", ["f: a port getter without a docstring whose port 'lambda' its "
                               "class's pydrake_system block does not name"]),
    ("get_tau_output_port", []),                  # its own docstring
    ("get_gain_output_port", ["f: no Parameters section (parameters i)"]),
    ("value", []),
    ("silent", ["f: no docstring"]),
])
def test_the_two_exemptions_are_rules_that_can_fail(name, problems):
    node = next(n for n in _node(_System).body if getattr(n, "name", None) == name)
    assert member_problems(_System, name, node, "f") == problems


def returns_descriptions() -> list[tuple[str, str]]:
    """(function, description) of every ``Returns`` entry of the package's functions."""
    out = []
    for path in sorted(PKG.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            doc = ast.get_docstring(node)
            if not doc:
                continue
            headers = list(_HEADER.finditer(doc))
            for i, header in enumerate(headers):
                if header.group(1).strip() != "Returns":
                    continue
                end = headers[i + 1].start() if i + 1 < len(headers) else len(doc)
                entries: list[list[str]] = []
                for line in doc[header.end():end].strip("\n").splitlines():
                    if line.strip() and not line[0].isspace():
                        entries.append([])
                    elif entries and line.strip():
                        entries[-1].append(line.strip())
                out += [(f"{_dotted(path)}.{node.name}", " ".join(e)) for e in entries]
    return out


def test_returns_entries_say_more_than_their_type():
    entries = returns_descriptions()
    thin = [(name, text) for name, text in entries if len(text.split()) <= 3]
    assert len(entries) > 200
    assert len(thin) <= THIN_RETURNS_MAX * len(entries), (
        f"{len(thin)} of {len(entries)} Returns entries say three words or fewer (name the "
        f"value in the summary instead, or say what it is): {thin[:20]}")


def _names_it(a):
    """The number of ``a``'s items.

    Parameters
    ----------
    a : list
        Items.
    """
    return len(a)


def _does_it(a):
    """Count ``a``'s items.

    Parameters
    ----------
    a : list
        Items.
    """
    return len(a)


def test_a_summary_that_names_the_value_stands_for_the_returns_section():
    assert member_problems(sys.modules[__name__], "_names_it", _node(_names_it), "f") == []
    assert member_problems(sys.modules[__name__], "_does_it", _node(_does_it), "f") == [
        "f: returns a value but has no Returns section"]
    assert summary_names_the_value("ρ(Φ) of the map.") and summary_names_the_value(
        "Whether it holds.") and not summary_names_the_value("Write the file.")

