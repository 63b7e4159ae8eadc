"""Sphinx configuration: MyST Markdown pages, notebooks executed by myst-nb, numpydoc API."""

import bayes_mpem

project = "bayes_mpem"
author = "bayes_mpem developers"
copyright = "2026, bayes_mpem developers"
release = version = bayes_mpem.__version__

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
]

# pages: Markdown (MyST) and the notebooks, which live in ../notebooks and are copied here
# by the build (see notebooks.md); they are executed at build time, never stored with outputs
# ".rst" first: autosummary writes its generated API stubs with the first suffix whose parser
# it takes for reStructuredText, and it mistakes myst-nb's for one; stubs written as ".md"
# showed their ``.. autofunction::`` directives as text (docs/check_api_pages.py checks)
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
myst_heading_anchors = 3
# maths: $...$ inline, $$...$$ and amsmath environments as display (rendered by MathJax)
myst_enable_extensions = ["dollarmath", "amsmath"]
suppress_warnings = ["myst.header"]

autosummary_generate = True
templates_path = ["_templates"]  # the module and class stubs document every public member
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

# no intersphinx: the build must work offline (CI has no network)

html_theme = "alabaster"
html_title = f"bayes_mpem {version}"

# the notebooks are kept in ../notebooks (stored without outputs); copy them in for the build
import shutil  # noqa: E402
from pathlib import Path  # noqa: E402

_here = Path(__file__).parent
(_here / "notebooks").mkdir(exist_ok=True)
for _nb in sorted((_here.parent / "notebooks").glob("*.ipynb")):
    shutil.copy2(_nb, _here / "notebooks" / _nb.name)
