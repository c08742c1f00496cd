"""Sphinx configuration of the ddatai + kgm documentation site.

Build it with ``python -m sphinx -b html docs docs/_build/html`` after
``pip install -e ".[docs]"`` (``tests/test_docs_build.py`` builds it with ``-W -n``: every warning
and every broken cross-reference fails the build).

Why Sphinx: the docstrings are written in numpydoc's format (as SciPy's and shapely's, whose
sites use Sphinx with the PyData theme and numpydoc), sphinx-gallery builds the gallery by
running the scene scripts themselves, and MyST reads the method documents of ``docs/`` as the
Markdown they are, so that they stay readable on their own in the repository.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "_ext"))

project = "ddatai + kgm"
author = "the ddatai developers"
copyright = "the ddatai developers, BSD-3-Clause"
from ddatai import __version__ as release  # noqa: E402  (cheap: no Taichi at import)

version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "ddatai_refs",  # docs/_ext: the docstrings' relative references (`GifStream`, `ddatai.start`)
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "README.md", "_templates", "gallery_scenes/*.ipynb", "gallery_scenes/*.py",
                    "gallery_scenes/*.zip", "gallery_scenes/*.codeobj.json", "gallery_scenes/*.md5",
                    "_ext"]
nitpicky = True  # every cross-reference must resolve
default_role = "obj"  # `Results` in a docstring links to its page
# names outside the project (the Python and NumPy/SciPy documentation is not fetched: the build
# needs no network), and words in backticks in the docstrings of the time step's modules
# (ddatai/step.py, start.py, solver.py, kernels/), which are being restructured: private
# helpers and members of modules documented by their module docstring only
nitpick_ignore_regex = [
    (r"py:.*", r"(enum|numpy|np|scipy|pickle|multiprocessing|concurrent|collections|typing|pathlib)(\..*)?"),
]
nitpick_ignore = [("py:obj", "coupled"), ("py:obj", "line_search"), ("py:obj", "slot_ab"), ("py:obj", "slot_ba"),
                  ("py:obj", "spsolve"), ("py:obj", "BlockPattern"), ("py:obj", "_anchored"),
                  ("py:obj", "REUSE_RESIDUAL"), ("py:obj", "REUSE_FLOOR")]

# ---------------------------------------------------------------------- Markdown (MyST)
myst_heading_anchors = 3
myst_enable_extensions: list = []

# ---------------------------------------------------------------------- API reference
autosummary_generate = True
autodoc_typehints = "none"  # numpydoc sections carry the types and units
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# ---------------------------------------------------------------------- theme
html_theme = "pydata_sphinx_theme"
html_title = "ddatai + kgm"
html_static_path: list = []
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_sidebars = {"index": [], "getting_started": []}

# ---------------------------------------------------------------------- the gallery
# sphinx-gallery runs every scene script as ``python scenes/NAME.py --gif ...`` would: its
# ``if __name__ == "__main__":`` block is the command line (`ddatai.cli.run_as_script`), so
# the gallery shows each scene's own code and the GIF that code writes (docs/_ext/gallery_helpers.py)
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "scenes"),
    "gallery_dirs": "gallery_scenes",
    "filename_pattern": r"\.py$",
    "ignore_pattern": r"__init__\.py",
    "within_subsection_order": "gallery_helpers.SceneOrder",
    "reset_argv": "gallery_helpers.scene_argv",
    "image_scrapers": ("gallery_helpers.gif_scraper",),
    "abort_on_example_error": True,  # a scene that fails fails the build
    "download_all_examples": False,
    "show_signature": False,
    "min_reported_time": 1e9,
    "remove_config_comments": True,
    "capture_repr": (),
}
