"""One name per thing: every ``from drake_coop.X import name`` in the package, the tests, the
benchmark, the docs' code blocks and the tutorials imports ``name`` from the module that
defines it (a function, class or assignment of its own), or from a package whose public
``__all__`` lists it — never through a module that merely imported it (an old path kept by a
re-export). A name that moved still answers at its old path with a ``DeprecationWarning``
(:mod:`drake_coop.control.deprecation`), checked here too.

Read with ``ast`` (nothing is run); the files of the robot path (``drake_coop/robot/``,
``tests/robot/``) are rewritten by their own branch and listed in :data:`PENDING` until then.
"""

import ast
import importlib
import json
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("drake_coop", "tests", "bench", "docs", "tutorials")
#: Folders whose old paths are moved by another branch (emptied when it is merged).
PENDING: tuple[str, ...] = ()


def _modules() -> dict[str, Path]:
    out = {}
    for path in (ROOT / "drake_coop").rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


MODULES = _modules()


def _own_names(module: str) -> set[str]:
    """The names a module defines at its top level (def, class, assignment)."""
    names = set()
    for node in ast.walk(ast.parse(MODULES[module].read_text(encoding="utf-8"))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
    return names


def _old_paths(source: str, where: str, own: dict) -> list[str]:
    found = []
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return found
    for node in ast.walk(tree):
        if not (isinstance(node, ast.ImportFrom) and node.level == 0
                and node.module in MODULES):
            continue
        module = node.module
        if module not in own:
            own[module] = _own_names(module)
        public = (getattr(importlib.import_module(module), "__all__", ())
                  if MODULES[module].name == "__init__.py" else ())
        for alias in node.names:
            name = alias.name
            if (name == "*" or f"{module}.{name}" in MODULES or name in own[module]
                    or name in public):
                continue
            found.append(f"{where}:{node.lineno}: {name} from {module}")
    return found


def scan(roots=SCANNED) -> list[str]:
    """Every import through an old path under ``roots`` (outside :data:`PENDING`)."""
    own: dict = {}
    found = []
    for root in roots:
        for path in sorted((ROOT / root).rglob("*")):
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith(PENDING) or "/_build/" in rel or "/generated/" in rel:
                continue
            if path.suffix == ".py":
                found += _old_paths(path.read_text(encoding="utf-8"), rel, own)
            elif path.suffix == ".ipynb":
                for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
                    if cell["cell_type"] == "code":
                        found += _old_paths("".join(cell["source"]), rel, own)
            elif path.suffix == ".md":
                for block in re.findall(r"```(?:python|py)\n(.*?)```",
                                        path.read_text(encoding="utf-8"), re.S):
                    found += _old_paths(block, rel, own)
    return found


def test_no_import_goes_through_an_old_path():
    assert scan() == []


def test_the_scan_sees_an_import_through_an_old_path(tmp_path):
    """The scan can fail: a name imported from a module that only imported it is found."""
    own: dict = {}
    source = ("from drake_coop.experiment.simulate import plan_run, simulate\n"
              "from drake_coop.experiment.plan import plan_run as p\n")
    assert _old_paths(source, "x.py", own) == [
        "x.py:1: plan_run from drake_coop.experiment.simulate"]


@pytest.mark.parametrize("old, name, new", [
    ("drake_coop.experiment.plan", "check_run_size", "drake_coop.experiment.ticks"),
    ("drake_coop.experiment.references", "waypoints", "drake_coop.scenario.task_path"),
    ("drake_coop.control.finger", "REFERENCE_ROWS", "drake_coop.control.reference_layout"),
    ("drake_coop.scenario.schema", "FORCE_SOURCES", "drake_coop.control.params"),
])
def test_a_moved_name_still_answers_at_its_old_path_with_a_warning(old, name, new):
    from drake_coop.control.deprecation import REMOVAL_DATE

    with pytest.warns(DeprecationWarning) as caught:
        value = getattr(importlib.import_module(old), name)
    assert value is getattr(importlib.import_module(new), name)
    message = str(caught[0].message)
    assert f"{old}.{name} moved to {new}.{name}" in message and REMOVAL_DATE in message
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
            getattr(importlib.import_module(old), "no_such_name")
