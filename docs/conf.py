"""Sphinx configuration of the roughslip documentation (``make docs``).

Math is typeset by a MathJax copy installed with the docs extra (sphinx-mathjax-offline) and
served from ``_static``: no page loads anything from the network. The configuration and CLI
references are generated from the code (docs/_ext/roughslip_docs.py, sphinx-click), and
the work-precision diagrams are made at build time by ``roughslip verify --quick --plot``, and
the other figures and console output by ``scripts/docs_figures.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

from roughslip import __version__  # noqa: E402

project = "roughslip"
author = "the roughslip developers"
copyright = "2026, the roughslip developers"
version = release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",
    "numpydoc",
    "sphinx_click",
    "myst_parser",
    "roughslip_docs",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_generated/*.txt", "_generated/*.rst"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]  # $...$ and $$...$$ on the Markdown pages
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # numpydoc sections carry the types
# defaults as written in the source (dtype=np.float64, not "<class 'numpy.float64'>")
autodoc_preserve_defaults = True
# "--set" stays two hyphens and quotes stay straight, on every page as typed
smartquotes = False
# every cross-reference must resolve (with -W, an unresolved one fails the build). A name that
# a module imports resolves to where it is documented (roughslip_docs.resolve_imported). Not
# checked: the outside packages and the standard library (no inventories of theirs are
# loaded: the build is offline), and private names (a leading underscore), which a docstring
# may name but the API reference does not document.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|scipy|pandas|xarray|h5py|matplotlib|click|collections|typing)\..*"),
    (r"py:.*", r"(.*\.)?_[a-zA-Z]\w*"),
]
html_theme = "alabaster"
# the theme's files, the MathJax copy and roughslip.css (wide console blocks and tables fit
# the column)
html_static_path = ["_static"]
html_show_sphinx = False  # no footer links to outside sites
html_theme_options = {"description": "static friction of rough elastic surfaces",
                      "fixed_sidebar": True,
                      # wide enough for two-panel figures and five-column tables
                      "page_width": "1180px", "body_max_width": "none"}
html_sidebars = {"**": ["about.html", "navigation.html", "searchbox.html"]}
suppress_warnings = ["myst.header"]
