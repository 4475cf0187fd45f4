"""The documentation site as a reader gets it: the built HTML, not the sources.

``test_api_page_*`` builds, with the site's own ``docs/conf.py``, extensions and templates, a
one-page site whose autosummary generates the :class:`~drake_coop.control.VelocityObserver`
page, and reads that page: its docstring, its ``Parameters``, its port table and port
descriptions, and equations rendered by a MathJax copied into the site (no CDN). Sphinx is in
the ``docs`` extra: without it these tests are skipped, unless ``DRAKE_COOP_REQUIRE_DOCS=1``
(CI sets it) makes the missing extra a failure.

``test_built_site_*`` reads a whole built site (``DRAKE_COOP_SITE=docs/_build/html``, set by
``.ci/run`` after its ``sphinx -W`` build): every generated API page documents its object.
"""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

PAGE = """# API test page

```{eval-rst}
.. currentmodule:: drake_coop.control

.. autosummary::
   :toctree: generated

   VelocityObserver

.. currentmodule:: drake_coop.control.params

.. autosummary::
   :toctree: generated

   check_gains
```

Math: $\\Lambda z + k_d z$.
"""


def _need_sphinx():
    if os.environ.get("DRAKE_COOP_REQUIRE_DOCS") == "1":
        import myst_nb  # noqa: F401
        import sphinx  # noqa: F401
    else:
        pytest.importorskip("sphinx", reason="the docs extra is not installed")
        pytest.importorskip("myst_nb", reason="the docs extra is not installed")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    _need_sphinx()
    src = tmp_path_factory.mktemp("src")
    out = src / "_build"
    (src / "index.md").write_text(PAGE, encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q",
                           "-b", "html", "-c", str(DOCS), str(src), str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out


def _text(html: str) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


def test_api_page_shows_the_docstring_parameters_and_ports(site):
    html = (site / "generated" / "drake_coop.control.VelocityObserver.html").read_text("utf-8")
    text = _text(html)
    assert ".. autoclass" not in text                      # the directive, run, not printed
    assert "Model-based joint-velocity observer" in text   # the docstring
    assert "Parameters" in text and "Number of joints." in text
    table = re.search(r'<table[^>]*class="[^"]*pydrake-system.*?</table>', html, flags=re.S)
    assert table, "no pydrake_system port table"
    cells = set(re.findall(r"<code[^>]*>\s*<span[^>]*>([\w]+)</span>", table.group(0))) or \
        set(re.findall(r"<code[^>]*>([\w]+)</code>", table.group(0)))
    assert {"q", "qddot_r_hat", "q_hat", "qdot_hat", "qdot_o"} <= cells
    # The numpydoc-style port sections (dropped by numpydoc) are shown as rubrics.
    assert "Input ports" in text and "Output ports" in text
    assert "Measured joint positions." in text
    assert "get_qddot_r_hat_input_port" in text and "set_initial_state" in text  # :members:


def test_function_page_shows_its_docstring(site):
    html = (site / "generated" / "drake_coop.control.params.check_gains.html").read_text("utf-8")
    assert ".. autofunction" not in _text(html)
    assert re.search(r'<dl class="py function"', html)


def test_math_is_rendered_by_a_local_mathjax(site):
    html = (site / "index.html").read_text("utf-8")
    scripts = re.findall(r'<script[^>]*src="([^"]+)"', html)
    assert not [s for s in scripts if "://" in s or s.startswith("//")], scripts
    local = [s for s in scripts if s.split("?")[0].endswith("mathjax/tex-mml-chtml.js")]
    assert local, scripts
    js = site / local[0].split("?")[0]
    assert js.is_file() and js.stat().st_size > 500_000 and b"MathJax" in js.read_bytes()
    assert (js.parent / "output" / "chtml" / "fonts" / "woff-v2" / "MathJax_Main-Regular.woff").is_file()
    assert r"\(\Lambda z + k_d z\)" in html


def test_built_site_every_api_page_documents_its_object():
    site = os.environ.get("DRAKE_COOP_SITE")
    if not site:
        pytest.skip("no built site: DRAKE_COOP_SITE=docs/_build/html (set by .ci/run)")
    pages = sorted((Path(site) / "api" / "generated").glob("*.html"))
    assert len(pages) > 100
    empty = [p.name for p in pages
             if not re.search(r'<dl class="py (class|function|data|exception|attribute)"',
                              p.read_text("utf-8"))
             or ".. auto" in _text(p.read_text("utf-8"))]
    assert empty == []
    observer = (Path(site) / "api" / "generated" /
                "drake_coop.control.VelocityObserver.html").read_text("utf-8")
    assert "pydrake-system" in observer and "Parameters" in observer


def test_port_sections_become_rubrics_before_the_numpydoc_sections():
    _need_sphinx()
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        from pydrake_system import move_port_sections
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    doc = ["Summary.", "", "Parameters", "----------", "n : int", "    Joints.", "",
           "Output ports", "------------", "a : m-vector", "b : m-vector", "    State only.", ""]
    assert move_port_sections(doc) == [
        "Summary.", "", ".. rubric:: Output ports", "", "``a`` : m-vector", "",
        "``b`` : m-vector", "    State only.", "", "", "Parameters", "----------", "n : int",
        "    Joints.", ""]


def _built_site() -> Path:
    site = os.environ.get("DRAKE_COOP_SITE")
    if not site:
        pytest.skip("no built site: DRAKE_COOP_SITE=docs/_build/html (set by .ci/run)")
    return Path(site)


def test_built_site_loads_the_wide_column_css():
    site = _built_site()
    assert (site / "_static" / "wide.css").read_text("utf-8") == \
        (DOCS / "_static" / "wide.css").read_text("utf-8")
    for page in ("index.html", "guide/object.html", "claims/object_carry.html"):
        assert re.search(r'<link[^>]+href="[./]*_static/wide\.css', (site / page).read_text("utf-8")), page


def test_built_site_prints_the_results_files_numbers():
    """The claims pages show the values their roles read (not the role's source text)."""
    site = _built_site()                  # skips without a built site (and its docs extra)
    sys.path.insert(0, str(DOCS / "_ext"))
    import results_role

    html = _text((site / "claims" / "force_sensing.html").read_text("utf-8")).replace("\xa0", " ")
    spec = "force_sensing:median(robot1.force_error.rms where force_source=observer) as .3f N"
    assert results_role.resolve(spec) in html
    assert "{result}" not in html and "force_source=observer)" not in html
    table = _text((site / "claims" / "object_carry.html").read_text("utf-8"))
    assert "result-table" not in table and "{sample as" not in table


def test_rebuilding_after_a_rerun_updates_the_numbers(tmp_path):
    """A study re-run (its results.csv rewritten) and an incremental rebuild: the prose and the
    generated table print the new values (the role notes the file as the page's dependency)."""
    _need_sphinx()
    from sphinx.application import Sphinx

    root = tmp_path / "repo"
    studies = root / "docs" / "figures" / "studies"
    studies.mkdir(parents=True)
    src = tmp_path / "src"
    src.mkdir()
    (src / "conf.py").write_text(
        f"import sys\nsys.path.insert(0, {str(DOCS / '_ext')!r})\n"
        f"extensions = ['myst_parser', 'results_role']\nresults_root = {str(root)!r}\n",
        encoding="utf-8")
    (src / "index.md").write_text(
        "# Numbers\n\nThe error is {result}`demo:max(worst.force_error.rms) as .3f N`.\n\n"
        "```{result-table} demo\n:header: case | error (mN)\n:each-row:\n"
        "{index as .0f} | {worst.force_error.rms as .1f [mN]}\n```\n", encoding="utf-8")

    def write(values):
        lines = ["index,worst.force_error.rms"] + [f"{i},{v}" for i, v in enumerate(values)]
        (studies / "demo_results.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")

    def build():
        app = Sphinx(str(src), str(src), str(tmp_path / "out"), str(tmp_path / "doctrees"),
                     "html", status=None, warning=None, freshenv=False, warningiserror=True)
        app.build()
        return _text((tmp_path / "out" / "index.html").read_text("utf-8")).replace("\xa0", " ")

    write([0.0123, 0.0456])
    first = build()
    assert "The error is 0.046 N" in first and "45.6" in first and "12.3" in first
    write([0.0123, 0.0456, 0.0789])
    second = build()
    assert "The error is 0.079 N" in second and "78.9" in second


def test_a_written_value_its_file_no_longer_gives_fails_the_build(tmp_path):
    """``{result}`VALUE <SPEC>```: the site prints VALUE (a short source name the page
    defines resolves); once the file gives another value the ``-W`` build fails, naming
    both, until ``results_role.py --write`` rewrites the page."""
    _need_sphinx()
    from sphinx.application import Sphinx
    from sphinx.errors import SphinxWarning

    root = tmp_path / "repo"
    studies = root / "docs" / "figures" / "studies"
    studies.mkdir(parents=True)
    src = tmp_path / "src"
    src.mkdir()
    (src / "conf.py").write_text(
        f"import sys\nsys.path.insert(0, {str(DOCS / '_ext')!r})\n"
        f"extensions = ['myst_parser', 'results_role']\nresults_root = {str(root)!r}\n",
        encoding="utf-8")
    (src / "index.md").write_text(
        "# Numbers\n\n<!-- result sources:\nd = demo\n-->\n\n"
        "The error is {result}`0.046 N <d:max(worst.force_error.rms) as .3f N>`.\n",
        encoding="utf-8")
    csv_path = studies / "demo_results.csv"

    def build(values, out):
        csv_path.write_text("index,worst.force_error.rms\n" + "".join(
            f"{i},{v}\n" for i, v in enumerate(values)), encoding="utf-8")
        warnings = io.StringIO()
        app = Sphinx(str(src), str(src), str(tmp_path / out), str(tmp_path / (out + "_doctrees")),
                     "html", status=None, warning=warnings, freshenv=True, warningiserror=True)
        try:
            app.build()
        except SphinxWarning as exc:          # older Sphinx: raised at the first warning
            return "", str(exc), 1
        html = _text((tmp_path / out / "index.html").read_text("utf-8")).replace("\xa0", " ")
        return html, warnings.getvalue(), app.statuscode

    # (a second Sphinx app in one process warns that Sphinx's own nodes are registered again:
    # only the role's warnings are looked at)
    html, warned, status = build([0.0123, 0.0456], "first")
    assert "The error is 0.046 N" in html and "{result} role" not in warned, warned
    # (a file of another size: the role caches a file by its modification time and size,
    # and two writes within one tick of a coarse file clock share the time)
    _, warned, status = build([0.0123, 0.07891], "second")
    assert status != 0 and "{result} role: written '0.046 N', the file gives '0.079 N'" in warned

