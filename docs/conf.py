"""Sphinx configuration of the sigma_des documentation site.

Build (warnings are errors, as in CI)::

    sphinx-build -W -b html docs docs/_build/html

Every reference page under ``reference/`` that lists keys, commands or files and the
two result pages under ``results/`` are generated during the build by the extensions
in ``docs/_ext/`` (nothing generated is committed): see ``docs/_ext/README.md``.
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
# the checkout's package wins over an installed one; _ext holds the site's own extensions
sys.path[:0] = [str(ROOT), str(DOCS / "_ext")]

from sigma_des.version import __version__  # noqa: E402

project = "sigma_des"
author = "the sigma_des authors"
copyright = "the sigma_des authors"  # noqa: A001 (Sphinx's name)
version = release = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinxarg.ext",
    "sphinx_copybutton",
    "sigma_docs",  # docs/_ext/sigma_docs.py: the generated reference and result pages
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"

# Pages the site is built from: index, glossary and changelog at the top, the rest in
# the reader folders. Any other top-level page (the former notes) is left out of the
# build, so nothing outside a toctree reaches the site (or breaks -W).
TOP_PAGES = {"index.md", "glossary.md", "changelog.md"}
exclude_patterns = [
    "_build",
    "_ext",
    "results/data",
    "img",
    "figures",
    "**/README.md",
    *sorted(p.name for p in DOCS.glob("*.md") if p.name not in TOP_PAGES),
]

myst_enable_extensions = ["colon_fence", "deflist", "fieldlist"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True
napoleon_attr_annotations = True

# autodoc resolves every type hint as a cross-reference; ones to third-party types
# (numpy arrays, simpy, pandas) have no target in an offline build
nitpicky = False

# command lines keep their "--" (no en dashes)
smartquotes = False

html_theme = "furo"
html_title = f"sigma_des {__version__}"
html_static_path: list[str] = []
html_show_sourcelink = False
copybutton_prompt_text = r"\$ |>>> "
copybutton_prompt_is_regexp = True
