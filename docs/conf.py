"""Sphinx configuration of the critfric manual: `make docs` builds it into docs/_build/html.

Markdown pages (MyST, with $...$ math), the gallery of docs/gallery/plot_*.py scripts run at
build time (sphinx-gallery), the API pages from the docstrings (autodoc, numpy style through
napoleon), and the references generated from the code itself (docs/_ext/critfric_refs.py:
the case-file keys from the schema, the commands from the typer app). The build needs no
network; it must give no warning (`sphinx-build -W`).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))  # the checkout's critfric, installed or not

os.environ.setdefault("MPLBACKEND", "Agg")  # the gallery's figures, without a display

from critfric._version import __version__

project = "critfric"
author = "the critfric authors"
copyright = "the critfric authors, MIT licence"
version = release = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
    "critfric_refs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = [
    "_build", "_generated", "_ext", "gallery",  # build output, included parts, sources
    "auto_examples/*.ipynb", "auto_examples/*.py", "auto_examples/*.zip",
    "auto_examples/*.md5", "auto_examples/*.json",
]
templates_path: list[str] = []

# --------------------------------------------------------------------------- MyST
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "substitution"]
myst_heading_anchors = 3  # [text](page.md#a-heading) links
myst_dmath_double_inline = True


def _constants() -> dict[str, str]:
    """The code's constants that the pages quote, as {{ name }} substitutions: a page says
    what the code does today, not what it did when the page was written."""
    from critfric.case.schema import SWEEP_GRADING
    from critfric.meshing.mesh import NEST_FRACTION
    from critfric.solvers import backends, eigen
    from critfric.sweep import extrapolate as x

    n = lambda v: f"{v:,}".replace(",", " ") if v >= 10_000 else str(v)
    return {
        "schur_max_contact": n(eigen.SCHUR_MAX_CONTACT),
        "schur_max_rows": n(2 * eigen.SCHUR_MAX_CONTACT),
        "auto_dense_rows_3d": n(eigen.AUTO_DENSE_ROWS_3D),
        "auto_dense_contact_3d": n(eigen.AUTO_DENSE_ROWS_3D // 3),
        "split_min_rows": n(backends.SPLIT_MIN_ROWS),
        "split_min_schur": n(backends.SPLIT_MIN_SCHUR),
        "infinite_tol": f"{eigen.INFINITE_TOL:g}",
        "residual_tol": f"{eigen.RESIDUAL_TOL:g}",
        "fit_sizes": str(x.FIT_SIZES),
        "min_order": f"{x.MIN_ORDER:g}",
        "weight_power": f"{x.WEIGHT_POWER:g}",
        "safety": f"{x.SAFETY:g}",
        "safety_few": f"{x.SAFETY_FEW:g}",
        "max_relative_error": f"{100 * x.MAX_RELATIVE_ERROR:g}%",
        "erratic": f"{100 * x.ERRATIC:g}%",
        "chain_tol": f"{100 * x.CHAIN_TOL:g}%",
        "error_floor": f"{x.ERROR_FLOOR:g}",
        "sweep_grading": f"{SWEEP_GRADING:g}",
        "nest_fraction": f"1/{round(1 / NEST_FRACTION)}",
    }


myst_substitutions = _constants()

# --------------------------------------------------------------------------- autodoc
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
python_use_unqualified_type_names = True
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False

# --------------------------------------------------------------------------- gallery
sphinx_gallery_conf = {
    "examples_dirs": "gallery",  # docs/gallery: plot_*.py and its GALLERY_HEADER.rst
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",  # every plot_*.py script runs at build time
    "ignore_pattern": r"__init__\.py",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "backreferences_dir": None,
    "remove_config_comments": True,
    "reset_modules": ("matplotlib",),
    "image_scrapers": ("gallery_scraper.tight",),  # whole titles and labels
    "show_memory": False,
    "default_thumb_file": str(HERE / "box_directions.png"),
}

# --------------------------------------------------------------------------- HTML
html_theme = "pydata_sphinx_theme"
html_title = f"critfric {version}"
html_theme_options = {
    "show_toc_level": 2,
    "navigation_depth": 2,
    "show_prev_next": True,
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars = {"index": []}
html_static_path: list[str] = []
html_last_updated_fmt = None
html_show_sourcelink = False
