"""Sphinx configuration of the drake_coop documentation.

Build (from the repository's root, warnings as errors):

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))

import drake_coop  # noqa: E402

project = "drake_coop"
author = "the drake_coop developers"
copyright = "2026, the drake_coop developers"
release = drake_coop.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_nb",                      # Markdown pages (MyST) and the tutorials' notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",                     # the package's docstrings are numpydoc
    "pydrake_system",               # docs/_ext: the LeafSystems' port blocks
    "scenario_fields",              # docs/_ext: the scenario reference, generated from the code
    "results_role",                 # docs/_ext: {result}`...`, numbers read from shipped results
]

# MyST: $...$ and $$...$$ math, amsmath environments, definition lists, heading anchors.
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 3
# The tutorials are shown with the outputs stored in them; they are executed by the test suite
# (tests/test_tutorials.py), not here: three of them run 10-90 s simulations.
nb_execution_mode = "off"

# ".rst" first: autosummary writes its generated pages (docs/api/generated/) with the first
# suffix parsed as reStructuredText, and a ".md" page holding reST directives would show them
# as text (every API page did, before this order).
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "_ext", "_templates", "**.ipynb_checkpoints",
                    "_generated/scenario_fields.md", "results/*.md"]
templates_path = ["_templates"]

autosummary_generate = True
autosummary_imported_members = False
# A name exported by two subpackages is indexed once, where it is defined; the other page says
# where (docs/_templates/autosummary/class.rst).
autosummary_context = {"aliases": {"drake_coop.scenario.Gains": "drake_coop.control.Gains"}}
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"          # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
# numpydoc renders the docstrings; their style is checked by review, not at build time.
numpydoc_validation_checks: set[str] = set()

html_theme = "alabaster"
html_title = f"drake_coop {release}"


def _stage_mathjax() -> Path:
    """MathJax 3 from the ``django-static-mathjax`` wheel (the ``docs`` extra; plain static
    files, no Django needed), staged under docs/_generated/mathjax_static/mathjax/: the one
    script Sphinx loads and the fonts it fetches next to itself (1.5 MB). The site then
    renders its equations with no network; a CDN would leave raw LaTeX on an offline machine."""
    import importlib.util

    spec = importlib.util.find_spec("mathjax")
    es5 = Path(next(iter(spec.submodule_search_locations))) / "static" / "mathjax" / "es5" \
        if spec and spec.submodule_search_locations else None
    if es5 is None or not (es5 / "tex-mml-chtml.js").is_file():
        raise RuntimeError("MathJax not found: install the documentation's extra, "
                           "pip install -e \".[docs]\" (django-static-mathjax)")
    static = DOCS / "_generated" / "mathjax_static"
    target = static / "mathjax"
    fonts = Path("output") / "chtml" / "fonts" / "woff-v2"
    (target / fonts).mkdir(parents=True, exist_ok=True)
    for rel in [Path("tex-mml-chtml.js")] + [fonts / f.name for f in (es5 / fonts).iterdir()]:
        if not (target / rel).exists() or (target / rel).read_bytes() != (es5 / rel).read_bytes():
            partial = (target / rel).with_name(f".{rel.name}.{os.getpid()}")
            shutil.copyfile(es5 / rel, partial)      # whole or not at all: two builds may race
            os.replace(partial, target / rel)
    return static


# Math rendered in the browser by a local MathJax (no CDN): _static/mathjax/tex-mml-chtml.js.
html_static_path = [str(_stage_mathjax()), "_static"]
# docs/_static/wide.css: a wider body column (alabaster's 940 px page cut YAML blocks and the
# split diagram), code blocks scrolled rather than cut, figures scaled to the column.
html_css_files = ["wide.css"]
mathjax_path = "mathjax/tex-mml-chtml.js"



def _copy_into_docs(folder: str, pattern: str) -> None:
    """Copy ``<checkout>/<folder>/<pattern>`` under ``docs/_generated/<folder>`` (sources must
    be under docs/; the repository keeps one copy: the tutorials the tests run, the diagrams
    ``drake-coop diagram`` writes)."""
    target = DOCS / "_generated" / folder
    target.mkdir(parents=True, exist_ok=True)
    for source in sorted((ROOT / folder).glob(pattern)):
        dest = target / source.name
        if not dest.exists() or dest.read_bytes() != source.read_bytes():
            partial = dest.with_name(f".{dest.name}.{os.getpid()}")
            shutil.copyfile(source, partial)      # whole or not at all: two builds may race
            os.replace(partial, dest)


def setup(app):
    app.connect("builder-inited", lambda app: _copy_into_docs("tutorials", "*.ipynb"),
                priority=100)
    app.connect("builder-inited", lambda app: _copy_into_docs("diagrams", "*.svg"),
                priority=100)
