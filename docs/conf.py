"""Sphinx configuration of the ffsr-gym documentation (MyST Markdown pages, the furo theme, autodoc + napoleon).

Build: ``pip install -e ".[docs]"`` then ``python -m sphinx -W -b html docs docs/_build/html``.
"""

from __future__ import annotations

from importlib.metadata import version as _version
from importlib.util import find_spec

project = "ffsr-gym"
author = "the ffsr-gym authors"
release = _version("ffsr-gym")
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
html_theme = "furo"
html_title = f"ffsr-gym {release}"
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# The extras' modules the API pages document (stable-baselines3, JAX, Dask) are mocked when they are not installed,
# so that the docs build with the docs extra alone; installed, they are imported as they are.
autodoc_mock_imports = [name for name in ("stable_baselines3", "torch", "jax", "jaxlib", "brax", "distributed", "optuna")
                        if find_spec(name) is None]
napoleon_google_docstring = True
napoleon_numpy_docstring = False


def _literal_bars(app, what, name, obj, options, lines):
    """Docstrings write absolute values and norms as ``|x|``; reST would read them as substitutions."""
    for i, line in enumerate(lines):
        if "|" in line and not line.lstrip().startswith(("|", "+")):
            lines[i] = line.replace("|", r"\|")


def setup(app):
    app.connect("autodoc-process-docstring", _literal_bars)
