"""The notebooks in notebooks/: stored without outputs, executed in CI, their API still there.

CI executes every notebook once, in the documentation build (``.ci/run``:
``sphinx-build -W`` with myst-nb's ``nb_execution_mode = "force"`` and
``nb_execution_raise_on_error = True`` in ``docs/conf.py``): a notebook that raises fails
the build, hence CI. The suite checks that this stays so, and, cheaply, that every name a
notebook imports or takes from an imported ``bayes_mpem`` module still exists (the usual way
a refactoring breaks a notebook). ``pytest --with-docs-build tests/test_notebooks.py`` also
executes them here, each in a fresh kernel.
"""

import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def _code(path):
    import nbformat

    nb = nbformat.read(path, as_version=4)
    return [c.source for c in nb.cells if c.cell_type == "code"]


def test_notebooks_are_stored_without_outputs():
    import nbformat

    assert NOTEBOOKS, "no notebooks found"
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        for cell in nb.cells:
            if cell.cell_type == "code":
                assert not cell.outputs and cell.execution_count is None, path.name


def _settings(conf: Path) -> dict:
    """The constant assignments of a Sphinx ``conf.py`` (read, not executed)."""
    out = {}
    for node in ast.parse(conf.read_text()).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                and isinstance(node.targets[0], ast.Name):
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
    return out


def test_ci_executes_every_notebook_and_fails_on_an_error():
    conf = _settings(ROOT / "docs" / "conf.py")
    assert conf["nb_execution_mode"] in ("force", "cache", "auto"), conf["nb_execution_mode"]
    assert conf["nb_execution_raise_on_error"] is True
    assert not conf.get("nb_execution_excludepatterns")
    assert conf["source_suffix"][".ipynb"] == "myst-nb"
    assert not any("notebooks" in p or "ipynb" in p.replace("ipynb_checkpoints", "")
                   for p in conf["exclude_patterns"])
    # every notebook is a page of the site (copied in by conf.py, listed in a toctree)
    listed = set(re.findall(r"^notebooks/(\w+)\s*$", (ROOT / "docs" / "index.md").read_text(),
                            flags=re.M))
    assert listed == {p.stem for p in NOTEBOOKS}, listed
    # and CI builds the site with warnings as errors, after the suite, with `set -e`
    ci = (ROOT / ".ci" / "run").read_text()
    assert "set -euo pipefail" in ci
    assert re.search(r"^[^#\n]*sphinx-build -W -b html docs ", ci, flags=re.M), ci


def _module(name: str):
    """The module of a dotted name, or None when it names no module."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError:
        return None


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_what_a_notebook_imports_exists(path):
    """Every import resolves, and every ``alias.name`` taken from an imported bayes_mpem
    module exists (``bm.diagnose``, ``diagnose_plots.plot_candidates``, ...)."""
    trees = [ast.parse(src) for src in _code(path)]  # a syntax error fails here
    modules, missing = {}, []  # alias -> dotted module name
    for node in (n for tree in trees for n in ast.walk(tree)):
        if isinstance(node, ast.Import):
            for a in node.names:
                importlib.import_module(a.name)
                modules[a.asname or a.name.split(".")[0]] = a.asname and a.name or \
                    a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                if _module(full) is not None:
                    modules[a.asname or a.name] = full
                elif not hasattr(importlib.import_module(node.module), a.name):
                    missing.append(f"from {node.module} import {a.name}")
    ours = {k: v for k, v in modules.items() if v.split(".")[0] == "bayes_mpem"}
    assert ours or any(isinstance(n, ast.ImportFrom) and n.module.startswith("bayes_mpem")
                       for tree in trees for n in ast.walk(tree)), path.name
    for node in (n for tree in trees for n in ast.walk(tree)):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id in ours:
            full = ours[node.value.id]
            if not hasattr(importlib.import_module(full), node.attr) \
                    and _module(f"{full}.{node.attr}") is None:
                missing.append(f"{full}.{node.attr}")
    assert not missing, f"{path.name}: {sorted(set(missing))}"


@pytest.mark.docs_build
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path):
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs
              if o.output_type == "error"]
    assert not errors
