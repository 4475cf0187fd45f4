"""The package's layers and the architecture page (docs/guide/architecture.md) against the code.

The import graph is read with ``ast`` from every module of ``drake_coop/`` (imports inside
functions included): it must have no circle and no arrow from a lower layer to a higher one;
the library ``drake_coop.control`` must load nothing of the package outside itself; the page's
module table must list every module and its layer list must be :data:`LAYERS`.
"""

import ast
import io
import re
import subprocess
import tokenize
import sys
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "drake_coop"
PAGE = ROOT / "docs" / "guide" / "architecture.md"

#: The package's layers, bottom first: a module may import its own layer's modules and lower
#: layers', never a higher layer's. A group is a subpackage (``control``) or a top-level module
#: (``cli``, ``console``); ``__init__``/``__main__`` of the package are the top.
LAYERS = [
    ("control", "kinematics"),
    ("scenario",),
    ("console", "sensing"),
    ("plant",),
    ("experiment",),
    ("identification", "results"),
    ("studies",),
    ("stability",),
    ("robot",),
    ("cli", "__main__"),
]
LAYER_OF = {group: i for i, groups in enumerate(LAYERS) for group in groups}


def package_modules() -> dict[str, Path]:
    """``dotted name -> file`` of every module of the package."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _imported(name: str, path: Path, node, modules) -> list[str]:
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    if isinstance(node, ast.Import):
        found = [alias.name for alias in node.names]
    else:
        base = node.module or ""
        if node.level:
            anchor = package
            for _ in range(node.level - 1):
                anchor = anchor.rpartition(".")[0]
            base = f"{anchor}.{base}" if base else anchor
        found = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                 for a in node.names]
    result = []
    for target in found:
        if target.split(".")[0] != "drake_coop":
            continue
        while target not in modules:          # a name inside a module: the module
            target = target.rpartition(".")[0]
        result.append(target)
    return result


def import_graph() -> dict[str, set[str]]:
    """``module -> modules of the package it imports`` (anywhere in its file)."""
    modules = package_modules()
    graph = defaultdict(set)
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                graph[name].update(t for t in _imported(name, path, node, modules) if t != name)
    return graph


def group_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_every_group_has_a_layer():
    groups = {group_of(m) for m in package_modules()} - {"__init__"}
    assert groups == set(LAYER_OF), "declare each subpackage/top-level module in LAYERS"


def test_no_arrow_runs_back_up():
    upward = [f"{a} -> {b}" for a, targets in import_graph().items() for b in targets
              if group_of(b) != "__init__" and group_of(a) != "__init__"
              and LAYER_OF[group_of(b)] > LAYER_OF[group_of(a)]]
    assert upward == []


def test_the_import_graph_has_no_circle():
    graph = import_graph()
    state: dict[str, int] = {}
    circles = []

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                circles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert circles == []


def test_the_graph_reader_sees_a_circle_and_an_upward_arrow(tmp_path, monkeypatch):
    """The two tests above can fail: a made-up package with a circle and an upward arrow."""
    pkg = tmp_path / "drake_coop"
    (pkg / "control").mkdir(parents=True)
    (pkg / "scenario").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "control" / "__init__.py").write_text("")
    (pkg / "scenario" / "__init__.py").write_text("")
    (pkg / "control" / "a.py").write_text("from drake_coop.scenario.b import x\n")
    (pkg / "scenario" / "b.py").write_text("def f():\n    from ..control import a\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", pkg)
    graph = import_graph()
    assert graph["drake_coop.control.a"] == {"drake_coop.scenario.b"}
    assert graph["drake_coop.scenario.b"] == {"drake_coop.control.a"}
    with pytest.raises(AssertionError):
        test_no_arrow_runs_back_up()
    with pytest.raises(AssertionError):
        test_the_import_graph_has_no_circle()


def test_the_library_loads_nothing_of_the_application():
    """Importing ``drake_coop.control`` and every one of its modules (its public names load
    on first use) loads no ``drake_coop`` module outside it, and nothing third-party but
    Drake and NumPy."""
    control = sorted(m for m in package_modules() if m.startswith("drake_coop.control"))
    code = ("import sys, importlib\n"
            "before = set(sys.modules)\n"
            f"for m in {control!r}: importlib.import_module(m)\n"
            "import drake_coop.control as c\n"
            "[getattr(c, n) for n in c.__all__]\n"
            "print('\\n'.join(sorted(m for m in sys.modules if m.startswith('drake_coop'))))\n"
            "print('third-party', *sorted({m.split('.')[0] for m in set(sys.modules) - before}\n"
            "                             - set(sys.stdlib_module_names)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout
    loaded, third_party = out.split("third-party")
    loaded = loaded.split()
    assert "drake_coop.control.block" in loaded
    outside = [m for m in loaded if m != "drake_coop" and not m.startswith("drake_coop.control")]
    assert outside == []
    assert set(third_party.split()) <= {"drake", "drake_coop", "numpy", "pydrake"}


# --- the architecture page ------------------------------------------------------------------

def _page() -> str:
    return PAGE.read_text(encoding="utf-8")


def test_the_page_lists_every_module():
    """Each module of the package is named in the page's module table (as ``folder/module.py``
    or, for a package's ``__init__``, as its folder), and the table names no module that does
    not exist."""
    table = [line for line in _page().splitlines() if line.startswith("| ")]
    named = set(re.findall(r"`([a-z_/]+(?:\.py)?)`", "\n".join(table)))
    files = {str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")}
    expected = {f for f in files if not f.endswith("__init__.py")}
    missing = sorted(f for f in expected if f not in named)
    assert missing == [], f"architecture.md's module table lacks {missing}"
    listed = {n for n in named if n.endswith(".py")}
    assert sorted(listed - files) == [], "architecture.md names modules that do not exist"


def test_the_page_states_the_layers_of_the_test():
    """The page's ``Layers`` list (one line per layer, bottom first) is :data:`LAYERS`."""
    section = _page().split("## Layers", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in section.splitlines() if re.match(r"\d+\. ", line)]
    stated = [tuple(re.findall(r"`([a-z_]+)`", line.split(":")[0])) for line in lines]
    assert stated == [tuple(layer) for layer in LAYERS]


def test_the_page_makes_no_false_claims():
    """Claims the page made that the code contradicted: the guards are no Simulator monitor
    (the runner checks them between ``AdvanceTo`` chunks), ``RunPlan`` is not computed once for
    everyone (the stability map and the benchmark make their own)."""
    page = _page()
    assert "monitor" not in page
    assert "computed once and read by everyone" not in page
    assert "between the chunks" in page and "between" in page
    simulate = (PACKAGE / "experiment" / "simulate.py").read_text(encoding="utf-8")
    assert "set_monitor(" not in simulate.replace("``simulator.set_monitor``", "")


def test_each_generated_diagram_has_one_copy():
    """The diagrams ``drake-coop diagram`` writes are kept once, in ``diagrams/``; the docs
    show them through a copy made at build time (``docs/conf.py``), never a committed one."""
    # docs/_generated and docs/_build are the build's own (ignored) copies, made by any
    # Sphinx build (tests/test_docs_site.py builds one with the site's conf).
    committed = [p for p in (ROOT / "docs").rglob("*.svg")
                 if (ROOT / "diagrams" / p.name).exists()
                 and not {"_generated", "_build"} & set(p.relative_to(ROOT / "docs").parts)]
    assert committed == []
    shown = set()
    for md in (ROOT / "docs").rglob("*.md"):
        shown |= set(re.findall(r"_generated/diagrams/([\w.]+\.svg)", md.read_text()))
    assert shown and all((ROOT / "diagrams" / name).is_file() for name in shown)


def test_no_public_name_of_the_control_layer_is_shadowed_by_a_submodule():
    """``from drake_coop.control import X`` gives the documented object whatever was imported
    before: a submodule named like one of the package's exports (a function ``f`` in
    ``control/f.py``) would replace it once the submodule is imported. The same for the
    packages that re-export their modules' names: ``control.object`` and ``cli`` (whose
    ``main`` is the console script's entry point)."""
    import importlib
    import inspect
    import pkgutil

    shadowed = []
    for name in ("drake_coop.control", "drake_coop.control.object", "drake_coop.cli"):
        package = importlib.import_module(name)
        for info in pkgutil.iter_modules(package.__path__):
            if info.name != "__main__":
                importlib.import_module(f"{name}.{info.name}")
        shadowed += [f"{name}.{export}" for export in package.__all__
                     if inspect.ismodule(getattr(package, export))]
    assert shadowed == []


#: The largest a module of the package may grow (lines): one concept a module.
MODULE_CODE_LINES_MAX = 400


def code_lines(text: str) -> int:
    """The lines of a module that hold code: not blank, not only a comment, not in a
    docstring (a module's, class's or function's, or a bare string under an attribute)."""
    tree = ast.parse(text)
    prose = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str):
            prose.update(range(node.lineno, node.end_lineno + 1))
    code = set()
    skip = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENDMARKER)
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type not in skip:
            code.update(range(tok.start[0], tok.end[0] + 1))
    return len(code - prose)


def test_no_module_is_longer_than_the_limit():
    """Every module of ``drake_coop/`` holds at most :data:`MODULE_CODE_LINES_MAX` lines of
    code (the architecture page's "one concept a module"; ``control/object.py`` had 1 195
    lines). Code lines, not lines: the cap is there to keep one concept a module, and a
    docstring that tells the reader the units, shapes and refusals is not a second concept
    (the cap on all lines, 600, split modules whose lines were mostly prose, and rewarded
    thinner docstrings). Docstrings' length is a review matter."""
    long = {name: n for name, path in package_modules().items()
            if (n := code_lines(path.read_text())) > MODULE_CODE_LINES_MAX}
    assert not long, f"modules over {MODULE_CODE_LINES_MAX} lines of code: {long}"
    assert len(package_modules()) > 50      # the reader found the package
    sample = '"""Module."""\n\n# a comment\nX = 1\n\n\ndef f(a):\n    """Doc.\n\n    More.\n    """\n' \
        '    return (a +\n            1)\n'
    assert code_lines(sample) == 4           # X = 1, def, and the two lines of the return


#: A reference to a tracker's item by number (the word issue and a number; a project's name,
#: a hash sign and a number): a reader of the repository cannot resolve it; the text says
#: what the thing is instead.
ISSUE_NUMBER = re.compile(r"\b[Ii]ssues? #?\d+|\b[A-Za-z_][\w-]* #\d{1,6}\b")


def _issue_references(root: Path, names: list[str]) -> list[str]:
    """``name:line: match`` for every reference by number in the text files ``names`` below
    ``root`` (a file with a NUL byte, or not UTF-8, is an image: not read)."""
    found = []
    for name in names:
        data = (root / name).read_bytes() if (root / name).is_file() else b""
        if b"\0" in data:
            continue
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            continue
        found += [f"{name}:{n}: {m.group(0)}" for n, line in enumerate(text.splitlines(), 1)
                  for m in ISSUE_NUMBER.finditer(line)]
    return found


def test_no_file_refers_to_an_issue_by_number(tmp_path):
    """Every file git tracks that is text: code, pages, scenarios, the result files'
    ``about`` texts (``docs/results/*.json``), the studies' files (``studies/``: their YAML,
    JSON, CSV and text tables), the CI script."""
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    assert ISSUE_NUMBER.search("as iss" + "ue 3 asks") and ISSUE_NUMBER.search("lib " + "#7")
    assert not ISSUE_NUMBER.search("colour #1f77b4, Fig. 3, (29)")
    # the scan reads the kinds of file a reference was found in before
    for kind in ("docs/results/", "studies/", "tests/", "docs/"):
        assert any(f.startswith(kind) for f in files), kind
    assert any(f.startswith("docs/results/") and f.endswith(".json") for f in files)
    assert any(f.startswith("studies/") and not f.endswith((".py", ".yaml")) for f in files)
    (tmp_path / "r.json").write_text('{"about": "measured for iss' + 'ue 12"}\n')
    (tmp_path / "t.csv").write_text('case,note\n1,"lib #' + '7"\n')
    (tmp_path / "p.png").write_bytes(b"\x89PNG\0issue 3")
    assert _issue_references(tmp_path, ["r.json", "t.csv", "p.png"]) == [
        "r.json:1: iss" + "ue 12", "t.csv:2: lib #" + "7"]
    found = _issue_references(ROOT, files)
    assert not found, found
