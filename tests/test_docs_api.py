"""The API reference (docs/api/*.md) names every public name of the package.

Public names, read from the sources with :mod:`ast` (no import, no Sphinx):

* each subpackage's ``__all__`` (the names ``from drake_coop.<sub> import ...`` gives), looked
  for in ``docs/api/<sub>.md``;
* each module's public classes and functions (module level, no leading underscore; only those
  in the module's ``__all__`` when it has one), looked for under the module's own heading;
* a package inside a subpackage (``control/object/``) or at the top (``cli/``) is read as one
  module: its ``__init__``'s ``__all__`` (the names it re-exports from its modules), and each
  of its modules' public names it does not re-export, under the module's heading.

A name added to the package without its line in the API reference fails here.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "drake_coop"
API = ROOT / "docs" / "api"
TOP_LEVEL = ("cli", "console")      # documented in docs/api/commands.md


def _dunder_all(tree: ast.Module) -> list[str] | None:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return [e.value for e in node.value.elts]
    return None


def public_names(path: Path) -> list[str]:
    """Module-level public classes and functions of one source file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = [n.name for n in tree.body
             if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")]
    listed = _dunder_all(tree)
    return names if listed is None else [n for n in names if n in listed]


def subpackages() -> list[str]:
    return sorted(p.parent.name for p in PKG.glob("*/__init__.py")
                  if p.parent.name != "data" and p.parent.name not in TOP_LEVEL)


def module_names(path: Path, dotted: str) -> list[tuple[str, str]]:
    """``(section, name)`` of the public classes and functions of a module file, or of a
    package folder read as one module (under its own heading the names its ``__all__``
    re-exports, under each module's heading the others)."""
    if path.is_dir():
        exported = _dunder_all(ast.parse((path / "__init__.py").read_text())) or []
        out = []
        for module in sorted(path.glob("*.py")):
            if not module.name.startswith("_"):
                out += [(dotted if name in exported else f"{dotted}.{module.stem}", name)
                        for name in public_names(module)]
        return out
    return [(dotted, name) for name in public_names(path)]


def module_sections(text: str) -> dict[str, str]:
    """``module -> the text under its '## `module`' heading`` of an API page."""
    parts = re.split(r"^## `([\w.]+)`\s*$", text, flags=re.M)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts) - 1, 2)}


def autosummary_entries(text: str) -> set[str]:
    """Names listed in the autosummary blocks of a chunk of an API page (indented lines)."""
    return set(re.findall(r"^ {3}~?([\w.]+)\s*$", text, flags=re.M))


def expected() -> list[tuple[str, str, str]]:
    """(api page, section, name) for every public name of the package."""
    out = []
    for sub in subpackages():
        exported = _dunder_all(ast.parse((PKG / sub / "__init__.py").read_text())) or []
        if not all(isinstance(name, str) for name in exported):
            # An __all__ computed in part (drake_coop.control's sources, from their
            # registry): the package's own list (its import loads no pydrake).
            import importlib

            exported = list(importlib.import_module(f"drake_coop.{sub}").__all__)
        out += [(sub, "", name) for name in exported]
        modules = [m for m in sorted((PKG / sub).glob("*.py")) if m.name != "__init__.py"]
        modules += sorted(p.parent for p in (PKG / sub).glob("*/__init__.py"))
        for module in modules:
            out += [(sub, section, name)
                    for section, name in module_names(module, f"drake_coop.{sub}.{module.stem}")
                    if name not in exported]
    for module in TOP_LEVEL:
        path = PKG / module if (PKG / module).is_dir() else PKG / f"{module}.py"
        out += [("commands", section, name)
                for section, name in module_names(path, f"drake_coop.{module}")]
    return out


def missing_names() -> list[str]:
    missing = []
    for page, section, name in expected():
        path = API / f"{page}.md"
        text = path.read_text(encoding="utf-8") if path.exists() else ""
        chunk = module_sections(text).get(section, "") if section else \
            text.split("\n## `", 1)[0]
        if name not in autosummary_entries(chunk):
            missing.append(f"{section or 'drake_coop.' + page}.{name} (docs/api/{page}.md)")
    return missing


def test_every_public_name_is_listed_in_the_api_reference():
    assert missing_names() == []


def test_every_subpackage_has_an_api_page_in_the_index():
    index = (API / "index.md").read_text(encoding="utf-8")
    assert [s for s in subpackages() if not re.search(rf"^{s}$", index, flags=re.M)] == []


def test_a_public_name_added_without_its_docs_is_reported(tmp_path, monkeypatch):
    # The check itself must be able to fail: a new public function in a copy of a module
    # whose API page does not list it is reported by name.
    pkg = tmp_path / "drake_coop"
    (pkg / "control").mkdir(parents=True)
    (pkg / "control" / "__init__.py").write_text('"""x"""\n')
    source = (PKG / "control" / "orthogonal.py").read_text(encoding="utf-8")
    (pkg / "control" / "orthogonal.py").write_text(source + "\n\ndef brand_new(x):\n    return x\n")
    monkeypatch.setitem(globals(), "PKG", pkg)
    monkeypatch.setitem(globals(), "TOP_LEVEL", ())
    missing = missing_names()
    assert missing == ["drake_coop.control.orthogonal.brand_new (docs/api/control.md)"]


@pytest.mark.parametrize("text, names", [
    ("```{eval-rst}\n.. autosummary::\n   :toctree: generated\n\n   Foo\n   bar\n```\n",
     {"Foo", "bar"}),
    ("Foo is mentioned in prose only.\n", set()),
])
def test_only_autosummary_entries_count_as_documented(text, names):
    assert autosummary_entries(text) == names


# ---------------------------------------------------------------- repository metadata


def test_citation_cff_is_valid_yaml_with_the_required_keys_and_this_version():
    from pydrake.common.yaml import yaml_load

    cff = yaml_load(filename=str(ROOT / "CITATION.cff"))
    assert {"cff-version", "message", "title", "authors"} <= set(cff)
    assert cff["cff-version"].startswith("1.2")
    assert all("name" in a or "family-names" in a for a in cff["authors"])
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    version = re.search(r'^version = "([^"]+)"', pyproject, flags=re.M).group(1)
    init = (PKG / "__init__.py").read_text(encoding="utf-8")
    assert cff["version"] == version
    assert f'__version__ = "{version}"' in init
    assert f"## {version}" in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")


def _repository_files() -> list[Path]:
    """The files git tracks (and would track) in a checkout; every file below the root
    otherwise. Build products (``*.egg-info``, a virtual environment) are not the repository."""
    import subprocess
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                             cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return [p for p in ROOT.rglob("*") if not any(part.endswith(".egg-info")
                                                      for part in p.relative_to(ROOT).parts)]
    return [ROOT / name for name in out.decode().split("\0") if name]


def test_no_file_refers_to_a_folder_outside_the_repository():
    needles = ["../" + "shared", "/work/" + "shared", "equations" + ".md"]
    skip = {".git", "_build", "_generated", "generated", "__pycache__", ".ipynb_checkpoints"}
    found = []
    for path in _repository_files():
        if skip & set(path.relative_to(ROOT).parts) or not path.is_file():
            continue
        if path.suffix not in (".py", ".md", ".yaml", ".toml", ".cff", ".ipynb", ".txt", ""):
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        found += [f"{path.relative_to(ROOT)}: {n}" for n in needles if n in text]
    assert found == []


def test_pydrake_system_blocks_are_read_into_their_ports():
    pytest.importorskip("sphinx")                       # the docs extension imports Sphinx
    import sys
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        from pydrake_system import parse_block
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))
    block = parse_block(["name: Controller", "input_ports:", "- q", "- reference",
                         "output_ports: [tau, qddot_r_hat]"])
    assert block == {"name": "Controller", "input_ports": ["q", "reference"],
                     "output_ports": ["tau", "qddot_r_hat"]}
    with pytest.raises(ValueError, match="expected one of name"):
        parse_block(["name: X", "inputs: [q]"])
    with pytest.raises(ValueError, match="no name"):
        parse_block(["input_ports: [q]"])


def test_readme_and_getting_started_state_the_same_timings():
    """Each timing is measured once and stated alike where it is stated: the paper run's wall
    time, the whole suite's and the fast tests' time (no second, different figure; neither
    page states one that no results file holds)."""
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    guide = " ".join((ROOT / "docs" / "guide" / "getting_started.md").read_text(
        encoding="utf-8").split())
    patterns = [r"about (\d+) s of wall time", r"about (\d+) min on 2 cores",
                r"fast ones only \(([\d.]+) min of CPU time"]
    for pattern in patterns:
        found = {re.findall(pattern, readme)[0] if re.findall(pattern, readme) else None,
                 re.findall(pattern, guide)[0] if re.findall(pattern, guide) else None}
        assert len(found) == 1, (pattern, found)       # the same figure, or none in either
    assert "1–1.5 min" not in guide and "about 2 min" not in readme


DOCS = ROOT / "docs"
_FENCE = re.compile(r"^(`{3,}|~{3,}).*?^\1\s*$", re.S | re.M)
_SPAN = re.compile(r"(?<![`{}])(`+)(?!`)((?:(?!\n[ \t]*\n).)*?)(?<!`)\1(?!`)", re.S)
_TEX = re.compile(r"\\[A-Za-z]+|[_^]\{")


def _pages() -> list[Path]:
    return [p for p in sorted(DOCS.rglob("*.md"))
            if not {"_build", "_generated"} & set(p.parts)]


def _code_spans(text: str) -> list[str]:
    text = re.sub(r"\{[\w:-]+\}`[^`]*`", " ", _FENCE.sub(" ", text))     # roles, fences
    return [m.group(2) for m in _SPAN.finditer(text)]


def test_no_tex_inside_code_spans_on_any_page():
    """Math is math ($...$, ```{math}```), never TeX shown as code."""
    found = [f"{p.relative_to(DOCS)}: `{s}`" for p in _pages()
             for s in _code_spans(p.read_text(encoding="utf-8")) if _TEX.search(s)]
    assert not found, "TeX in code spans:\n" + "\n".join(found)


def test_the_tex_detector_finds_a_tex_code_span():
    assert [s for s in _code_spans("a `t_{k+1}` and `\\dot q` but `q_d` and $t_{k}$")
            if _TEX.search(s)] == ["t_{k+1}", "\\dot q"]


def test_no_equation_inside_a_table_of_the_object_guide():
    """The object guide's equations are displayed math, not code spans in wrapping cells."""
    rows = [line for line in (DOCS / "guide" / "object.md").read_text(encoding="utf-8")
            .splitlines() if line.lstrip().startswith("|")]
    cells = [s for row in rows for s in _code_spans(row) if "=" in s or "$" in s]
    maths = [row for row in rows if re.search(r"(?<!\\)\$[^$]+\$", row)]
    assert not cells and not maths, cells + maths


def test_the_index_shelves_the_pages_as_tutorials_how_to_reference_explanation():
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    trees = re.findall(r"```\{toctree\}\n(.*?)```", index, re.S)
    shelves = {}
    for tree in trees:
        caption = re.search(r"^:caption:\s*(.+)$", tree, re.M)
        assert caption, "a toctree without a caption"
        shelves[caption.group(1).strip()] = [line.strip() for line in tree.splitlines()
                                             if line.strip() and not line.startswith(":")]
    assert list(shelves) == ["Tutorials", "How-to guides", "Reference", "Explanation"]
    assert "api_usage" in shelves["How-to guides"]          # the library's how-to, named
    assert not any("*" in e for entries in shelves.values() for e in entries)  # no catch-all
    listed = {e for entries in shelves.values() for e in entries}
    top = {p.stem for p in DOCS.glob("*.md") if p.stem != "index"}
    assert top <= listed, f"pages on no shelf: {sorted(top - listed)}"


def test_the_body_column_is_widened_by_the_sites_css():
    css = (DOCS / "_static" / "wide.css").read_text(encoding="utf-8")
    assert re.search(r"div\.document\s*\{[^}]*max-width:\s*1[2-9]\d\dpx", css)
    assert re.search(r"div\.body\s*\{[^}]*max-width:\s*none", css)
    conf = (DOCS / "conf.py").read_text(encoding="utf-8")
    assert 'html_css_files = ["wide.css"]' in conf and '"_static"' in conf


_DOC_SPAN = re.compile(r"(?<!`)``(?!`)((?:(?!\n[ \t]*\n).)+?)``(?!`)", re.S)
_DOC_TEX = re.compile(r"[_^]\{|\\|\^T(?![A-Za-z])")
_DOC_COMMENT = re.compile(r"^[ \t]*#:(.*)$", re.M)


def _docstrings(source: str) -> list[tuple[int, str]]:
    """``(line, text)`` of a module's docstrings (module, classes, functions, the strings under
    an assignment) and of its ``#:`` comments (Sphinx's attribute docs), one per block."""
    tree = ast.parse(source)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                out.append((node.body[0].lineno, doc))
        body = getattr(node, "body", None)
        if isinstance(body, list):          # attribute docstrings: a string after an assignment
            for before, after in zip(body, body[1:]):
                if isinstance(before, (ast.Assign, ast.AnnAssign)) and isinstance(
                        after, ast.Expr) and isinstance(after.value, ast.Constant) \
                        and isinstance(after.value.value, str):
                    out.append((after.lineno, after.value.value))
    block, start = [], 0
    for number, line in enumerate(source.splitlines() + [""], 1):
        m = _DOC_COMMENT.match(line)
        if m:
            start = start or number
            block.append(m.group(1))
        elif block:
            out.append((start, "\n".join(block)))
            block, start = [], 0
    return out


def docstring_tex_spans(source: str) -> list[tuple[int, str]]:
    """``(line, span)`` of every double-backtick span of the docstrings holding TeX
    (``t_{k+1}``, ``J_x^{+T}``, a backslash, ``J^T``): shown as raw TeX on the API pages."""
    return sorted((line, m.group(1)) for line, doc in _docstrings(source)
                  for m in _DOC_SPAN.finditer(doc) if _DOC_TEX.search(m.group(1)))


def _package_tex_spans() -> dict[str, list[tuple[int, str]]]:
    found = {}
    for path in sorted(PKG.rglob("*.py")):
        spans = docstring_tex_spans(path.read_text(encoding="utf-8"))
        if spans:
            found[path.relative_to(PKG).as_posix()] = spans
    return found


def tex_span_problems(found: dict[str, list[tuple[int, str]]]) -> list[str]:
    """One line per TeX span found, naming the file and the line."""
    return [f"drake_coop/{f}:{line}: ``{s}`` (use :math:)" for f, spans in found.items()
            for line, s in spans]


def test_no_tex_inside_code_spans_in_the_docstrings():
    """The API pages show math as math (``:math:`t_{k+1}```), never raw TeX in a code span;
    no module is exempt."""
    problems = tex_span_problems(_package_tex_spans())
    assert not problems, "\n".join(problems)


def test_a_tex_span_is_reported_with_its_file_and_line():
    found = {"a.py": [(3, "t_{k+1}")], "b.py": [(5, "J^T")]}
    assert tex_span_problems(found) == ["drake_coop/a.py:3: ``t_{k+1}`` (use :math:)",
                                        "drake_coop/b.py:5: ``J^T`` (use :math:)"]
    assert tex_span_problems({}) == []


def escaped_docstrings(source: str) -> list[int]:
    r"""Lines of the module, class and function docstrings written with a backslash that are
    not raw strings: math is written as the docs show it (a raw docstring holding
    ``\dot q``), never with doubled backslashes nor with an escape Python would take
    (``"\theta"`` holds a tab)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) \
                and node.body and isinstance(node.body[0], ast.Expr) \
                and isinstance(node.body[0].value, ast.Constant) \
                and isinstance(node.body[0].value.value, str):
            text = ast.get_source_segment(source, node.body[0])
            if "\\" in text and text[:1] not in "rR":
                out.append(node.body[0].lineno)
    return sorted(out)


def test_every_docstring_with_a_backslash_is_raw():
    found = [f"drake_coop/{path.relative_to(PKG).as_posix()}:{line}"
             for path in sorted(PKG.rglob("*.py"))
             for line in escaped_docstrings(path.read_text(encoding="utf-8"))]
    assert not found, "docstrings with a backslash that are not raw:\n" + "\n".join(found)


def test_the_escape_detector_finds_a_non_raw_docstring_with_a_backslash():
    source = '''"""Module: ``\\\\dot q``."""


def f():
    r"""Raw: :math:`\\dot q`."""


class C:
    """Plain, no backslash."""

    def g(self):
        """Tab: \\theta."""
'''
    assert escaped_docstrings(source) == [1, 12]


def test_the_docstring_tex_detector_finds_tex_spans_and_skips_math_and_plain_code():
    source = '''"""Held on ``[t_k, t_{k+1})``, ``J_x^{+T}`` of ``J_xᵀ``, ``q_d``."""

X = 1
"""``\\\\dot q`` and :math:`t_{k+1}` and ``J^T F``."""


def f():
    """``q(k)``, ``Σ_{j<k} a_j``."""


#: published at ``t_{k+1}``,
#: not at ``t_k``.
Y = 2
'''
    assert docstring_tex_spans(source) == [
        (1, "J_x^{+T}"), (1, "[t_k, t_{k+1})"), (4, "J^T F"), (4, "\\dot q"),
        (8, "Σ_{j<k} a_j"), (11, "t_{k+1}")]
