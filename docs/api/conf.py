"""Sphinx configuration of cagekit's API reference (make docs: out/docs/index.html).

The reference pages are generated from the docstrings (NumPy style, read by numpydoc) by
autosummary, recursively over ``cagekit``'s subpackages and modules and ``cagekit_learn``;
``cagekit`` itself loads its public names lazily (PEP 562), so its subpackages are listed
rather than its namespace. The gallery runs the README's examples (docs/examples).
The build runs offline: no intersphinx.
"""

import os
import re
import sys
import types
from pathlib import Path

import sphinx.ext.autosummary as _autosummary

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
# matplotlib without a display, as the tests run it
os.environ.setdefault("MPLBACKEND", "Agg")

# cagekit/cli/__main__.py is ``python -m cagekit.cli``: importing it runs the command line
# (which then reads sphinx-build's arguments). autosummary's recursive listing imports every
# submodule; a stand-in marked as a mock makes it skip this one (it holds no API).
_cli_main = types.ModuleType("cagekit.cli.__main__")
_cli_main.__sphinx_mock__ = True
sys.modules["cagekit.cli.__main__"] = _cli_main

# autosummary's one-line summaries end at the first ". ", even inside an inline literal
# (``mean_i (1 - |n_i(X) . n_i^0|)`` is cut in half and warns; its check that a cut does not
# break inline markup parses the whole stanza, not the cut). A sentence's period follows a
# character, never a space, so a period after a space does not end one here.
_autosummary.periods_re = re.compile(r"(?<!\s)\.(?:\s+)")

project = "cagekit"
author = "cagekit contributors"
copyright = "cagekit contributors"
release = version = "0.1.0"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

templates_path = ["_templates"]
exclude_patterns = ["_build"]
root_doc = "index"
html_theme = "alabaster"
html_title = "cagekit API reference"

# autosummary writes one page per module, class and function (under generated/)
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "none"  # numpydoc's Parameters sections state the types

# numpydoc: autosummary already lists a class's members; numpydoc's own member tables
# would point at pages that are not generated
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

# Cross-references to other projects (numpy, torch, ...) cannot resolve offline without
# intersphinx; unresolved ones stay plain text rather than warnings
nitpicky = False

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "docs" / "examples"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "plot_gallery": True,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
}
