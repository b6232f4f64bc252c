"""Sphinx configuration of navsim's documentation site.

Build it (warnings are errors; the tutorials are executed):

    python -m sphinx -W -b html docs docs/_build/html
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))            # this checkout's navsim, also when another is installed
# ... and in the kernels that execute the tutorials
os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
os.environ.setdefault("MPLBACKEND", "Agg")

from navsim.version import __version__  # noqa: E402

project = "navsim"
author = "navsim developers"
copyright = "2026, navsim developers"
version = release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "numpydoc",
    "myst_nb",                 # Markdown pages (MyST) and the tutorials, executed at build time
    "sphinxarg.ext",           # the command line, generated from navsim.cli.build_parser
]
source_suffix = {".md": "myst-nb"}
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**.ipynb_checkpoints", "jupyter_execute"]
root_doc = "index"

# the tutorials ran when the site was built: their numbers and figures are today's
nb_execution_mode = "force"
nb_execution_raise_on_error = True          # a tutorial that fails fails the build
nb_execution_timeout = 300
nb_execution_show_tb = True
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "none"                  # numpydoc's Parameters sections say the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

smartquotes = False                         # "--force" stays two hyphens

html_theme = "furo"
html_title = f"navsim {release}"
html_static_path = []
