"""Sphinx configuration of the HumV-USD manual (``make docs``; tests/test_docs.py builds it too).

Sphinx reads the code's numpydoc docstrings (autodoc + napoleon) and the click commands
(sphinx-click); MyST-Parser lets the pages be Markdown like the rest of the repository's prose;
furo is the theme. Built offline with warnings as errors and nitpicky cross-references:
``sphinx -W --keep-going -n``. Reference pages are generated from the single sources at build
time by ``docs/_ext/humv_docs.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))

project = "HumV-USD"
author = "the HumV-USD developers"
copyright = "2026, the HumV-USD developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    # MathJax 3.2.2 shipped in the wheel and copied to _static/mathjax: the maths shows offline
    # (Sphinx's default loads MathJax from a CDN); tests/test_docs.py checks no page loads a
    # script from the network
    "sphinx-mathjax-offline",
    "sphinx_click",
    "humv_docs",
    "humv_figures",  # the physics pages' bench figures, drawn from docs/physics/data/*.csv
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "Thumbs.db", ".DS_Store"]

myst_enable_extensions = ["colon_fence", "deflist", "dollarmath", "fieldlist"]
myst_heading_anchors = 3

# every cross-reference must resolve (-n); references to other libraries' objects are not
# checked (the build is offline, no intersphinx inventories)
nitpicky = True
nitpick_ignore_regex = [(r"py:.*", r"(?!humv_usd\b).*")]

autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

html_theme = "furo"
html_title = "HumV-USD manual"
html_static_path = ["_static"]
html_css_files = ["humv.css"]  # the physics pages' agreement tables
html_show_sourcelink = False

# quotes and ellipses only: "--from" in command help must stay two hyphens, not an en dash
smartquotes_action = "qe"
