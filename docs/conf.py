"""Sphinx configuration of the drake_coop documentation.

Build (from the repository's root, warnings as errors):

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

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
]

# MyST: $...$ and $$...$$ math, amsmath environments, definition lists, heading anchors.
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 3
# The tutorials are shown with the outputs stored in them; they are executed by the test suite
# (tests/test_tutorials.py), not here: three of them run 10-90 s simulations.
nb_execution_mode = "off"

source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "_ext", "_templates", "**.ipynb_checkpoints",
                    "_generated/scenario_fields.md"]
templates_path = ["_templates"]

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"          # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
# numpydoc renders the docstrings; their style is checked by review, not at build time.
numpydoc_validation_checks: set[str] = set()

html_theme = "alabaster"
html_title = f"drake_coop {release}"
html_static_path: list[str] = []



def _copy_into_docs(folder: str, pattern: str) -> None:
    """Copy ``<checkout>/<folder>/<pattern>`` under ``docs/_generated/<folder>`` (sources must
    be under docs/; the repository keeps one copy: the tutorials the tests run, the diagrams
    ``drake-coop diagram`` writes)."""
    target = DOCS / "_generated" / folder
    target.mkdir(parents=True, exist_ok=True)
    for source in sorted((ROOT / folder).glob(pattern)):
        dest = target / source.name
        if not dest.exists() or dest.read_bytes() != source.read_bytes():
            shutil.copyfile(source, dest)


def setup(app):
    app.connect("builder-inited", lambda app: _copy_into_docs("tutorials", "*.ipynb"),
                priority=100)
    app.connect("builder-inited", lambda app: _copy_into_docs("diagrams", "*.svg"),
                priority=100)
