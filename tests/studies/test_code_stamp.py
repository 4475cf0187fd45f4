"""The code stamp: a docstring or comment edit leaves it, a code edit changes it, and it
depends neither on where the package is nor on file order; its docstring detection agrees
with the abstract syntax tree's on every module of the package."""

from __future__ import annotations

import ast
import io
import os
import shutil
import subprocess
import sys
import tokenize
from importlib import metadata
from pathlib import Path

import pytest

import drake_coop
from drake_coop.studies.code_stamp import (
    code_stamp,
    package_sources,
    source_fingerprint,
    strip_source,
)

PACKAGE = Path(drake_coop.__file__).parent

MODULE = '''"""A module's docstring."""

import math  # a trailing comment

LIMIT = 4_000_000


class Box:
    """A class's docstring,
    on two lines."""

    size = 2.0

    def volume(self) -> float:
        """A method's docstring."""
        # a comment line
        return self.size ** 3 * LIMIT


def message(x):
    "A one-quoted docstring."
    label = "x is"
    print(f"{label} {x}")
    "".join(["a", "b"])
    f"{x!r:>{10}} is a bare f-string"  # kept: not a docstring
    return math.sqrt(x)
'''

#: MODULE stripped, written out by hand.
STRIPPED = """import math
LIMIT = 4_000_000
class Box:
    size = 2.0
    def volume(self) -> float:
        return self.size ** 3 * LIMIT
def message(x):
    label = "x is"
    print(f"{label} {x}")
    "".join(["a", "b"])
    f"{x!r:>{10}} is a bare f-string"
    return math.sqrt(x)"""
#: MODULE's fingerprint (computed on Python 3.11).
GOLDEN = "0369e198d267f838"

SAME = [   # edits of docstrings, comments and blank lines only
    ('"""A module\'s docstring."""', '"""Another text,\n\nover three lines."""'),
    ('"""A method\'s docstring."""', "'''A method's docstring, reworded.'''"),
    ("  # a trailing comment", ""),
    ("        # a comment line\n", "        # another comment\n\n        # and one more\n"),
    ('    "A one-quoted docstring."\n', ""),                                 # removed
    ("    def volume(self) -> float:\n", "    def volume(self) -> float:\n        'Added.'\n"),
    ("\n\nclass Box:", "\n\n\n\n# a section\nclass Box:"),
    ("    size = 2.0\n", "    size = 2.0   \n"),                             # trailing space
]

CHANGED = [   # edits of code
    ("LIMIT = 4_000_000", "LIMIT = 4_000_001"),
    ('label = "x is"', 'label = "x was"'),                  # a string that is a value
    ('print(f"{label} {x}")', 'print(f"{label}: {x}")'),    # an f-string
    ('"".join(["a", "b"])', '"".join(["a", "c"])'),          # a statement starting with a str
    ("        return self.size ** 3 * LIMIT", "        return self.size ** 2 * LIMIT"),
    ("    size = 2.0\n", "    size = 2.0\n    size = 3.0\n"),
    ("    return math.sqrt(x)", "    return math.sqrt(x)  # noqa\n    return 0"),
]


def _fp(text: str) -> str:
    return source_fingerprint({"pkg/mod.py": text})


@pytest.mark.parametrize("old, new", SAME)
def test_a_docstring_or_comment_edit_leaves_the_fingerprint(old, new):
    assert old in MODULE
    edited = MODULE.replace(old, new)
    ast.parse(edited)                                   # still a module
    assert _fp(edited) == _fp(MODULE)


@pytest.mark.parametrize("old, new", CHANGED)
def test_a_code_edit_changes_the_fingerprint(old, new):
    assert old in MODULE
    edited = MODULE.replace(old, new)
    ast.parse(edited)
    assert _fp(edited) != _fp(MODULE)


def test_the_stripped_source_and_its_fingerprint_are_the_same_on_every_python():
    """The tokenizer's f-string tokens differ from Python 3.12 on; the stripped text and the
    fingerprint do not (the value was written on Python 3.11; CI checks it on the others)."""
    assert strip_source(MODULE) == STRIPPED
    assert _fp(MODULE) == GOLDEN


def test_names_count_and_order_does_not():
    a, b = {"x.py": "A = 1\n", "y.py": "B = 2\n"}, {"y.py": "B = 2\n", "x.py": "A = 1\n"}
    assert source_fingerprint(a) == source_fingerprint(b)
    assert source_fingerprint(a) != source_fingerprint({"x.py": "B = 2\n", "y.py": "A = 1\n"})
    # the names and texts are delimited: moving a line from one module to the next shows
    assert source_fingerprint({"x.py": "A = 1\nB = 2\n", "y.py": "C = 3\n"}) != \
        source_fingerprint({"x.py": "A = 1\n", "y.py": "B = 2\nC = 3\n"})


def test_an_untokenizable_source_is_refused_in_one_line():
    with pytest.raises(ValueError, match="^source: does not tokenize"):
        strip_source('x = """never closed\n')


def _ast_docstring_spans(text: str) -> list[tuple[tuple, tuple]]:
    """(start, end) of every statement that is a string constant, from the syntax tree
    (columns converted from UTF-8 bytes to characters)."""
    lines = text.splitlines(keepends=True)

    def char_col(row: int, col: int) -> int:
        return len(lines[row - 1].encode("utf-8")[:col].decode("utf-8"))

    return sorted(((n.lineno, char_col(n.lineno, n.col_offset)),
                   (n.end_lineno, char_col(n.end_lineno, n.end_col_offset)))
                  for n in ast.walk(ast.parse(text))
                  if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)
                  and isinstance(n.value.value, (str, bytes)))


def _expected_strip(text: str) -> str:
    """The source with the syntax tree's string statements and the tokenizer's comments
    blanked out, blank lines and trailing spaces dropped."""
    rows = [list(line) for line in text.splitlines(keepends=True)]
    comments = [(t.start, t.end) for t in tokenize.generate_tokens(io.StringIO(text).readline)
                if t.type == tokenize.COMMENT]
    for (r0, c0), (r1, c1) in _ast_docstring_spans(text) + comments:
        for r in range(r0, r1 + 1):
            a = c0 if r == r0 else 0
            b = c1 if r == r1 else len(rows[r - 1])
            for c in range(a, b):
                if rows[r - 1][c] not in "\r\n":
                    rows[r - 1][c] = " "
    kept = ("".join(row).rstrip() for row in rows)
    return "\n".join(line for line in kept if line)


def test_the_stripping_removes_what_the_syntax_tree_calls_docstrings_in_every_module():
    sources = package_sources()
    assert "studies/code_stamp.py" in sources and len(sources) > 100
    stripped_any = 0
    for name, text in sources.items():
        expected = _expected_strip(text)
        assert strip_source(text) == expected, name
        stripped_any += expected != "\n".join(l.rstrip() for l in text.splitlines() if l.strip())
    assert stripped_any > 100          # the package's modules have docstrings and comments


def test_the_stamp_is_the_packages_fingerprint_and_drakes_version():
    digest, drake = code_stamp().split("+drake")
    assert digest == source_fingerprint(package_sources())
    assert len(digest) == 16 and int(digest, 16) >= 0
    assert drake == metadata.version("drake")


def test_a_copy_of_a_package_elsewhere_with_caches_has_the_same_fingerprint(tmp_path):
    studies = PACKAGE / "studies"
    copy = tmp_path / "elsewhere" / "studies"
    shutil.copytree(studies, copy)
    (copy / "__pycache__").mkdir(exist_ok=True)
    (copy / "__pycache__" / "stray.py").write_text("X = 1\n")    # not the package's
    original = source_fingerprint(package_sources(studies))
    assert sorted(package_sources(copy)) == sorted(package_sources(studies))
    assert "store.py" in package_sources(copy)
    assert source_fingerprint(package_sources(copy)) == original
    module = copy / "store.py"
    text = module.read_text(encoding="utf-8")
    module.write_text(text.replace('"""Results store', '"""The results store', 1)
                      + "\n# a comment at the end\n", encoding="utf-8")
    assert source_fingerprint(package_sources(copy)) == original
    module.write_text(text.replace("MAX_CASE_BYTES = 4_000_000", "MAX_CASE_BYTES = 4_000_001"),
                      encoding="utf-8")
    assert source_fingerprint(package_sources(copy)) != original


def test_another_process_in_another_folder_computes_the_same_stamp(tmp_path):
    env = {**os.environ, "PYTHONHASHSEED": "12345", "PYTHONDONTWRITEBYTECODE": "1"}
    out = subprocess.run([sys.executable, "-c", "from drake_coop.studies.code_stamp import "
                          "code_stamp; print(code_stamp())"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True).stdout.strip()
    assert out == code_stamp()


def test_a_docstring_ending_on_non_ascii_text_leaves_the_next_line_whole():
    """Python 3.12's tokenizer gives such a string's end column in UTF-8 bytes: the stripping
    must not eat the characters after it (the next line's indentation)."""
    text = ('class A:\n'
            '    def check(self):\n'
            '        """Each arm at ``t_k``,\n'
            '        ``λ̂(k)``, ``τ(k)`` and ``τ̂(k)`` (ω, θ)."""\n'
            '        t = (self.k - 1) * self.h\n'
            '        return t  # λ̂ too\n')
    assert strip_source(text) == ('class A:\n'
                                  '    def check(self):\n'
                                  '        t = (self.k - 1) * self.h\n'
                                  '        return t')
