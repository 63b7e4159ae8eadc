"""The package layout keeps its promises (docs/architecture.md).

Read from the source files with :mod:`ast`, without importing anything: imports
point down the layers only, the two wings never import each other, results
never import plots, there is no import cycle and no private name crosses a
module boundary; functions stay short. ``importlib`` calls count as imports.
"""

import ast
import importlib
from pathlib import Path

import pytest

import bayes_mpem

PKG = Path(bayes_mpem.__file__).resolve().parent

#: layer of each top-level part; a module may import only from its own part or lower layers
LAYER = {"_rng": 0, "exceptions": 0, "_validate": 0, "_threads": 0, "commands": 0,
         "io": 1,
         "acoustics": 2, "mixture": 2, "mcmc": 2,
         "lbl": 3, "survey_in": 3,
         "plots": 4, "report": 5, "batch": 5, "cli": 6}
WINGS = {"lbl", "survey_in"}
MAX_FUNCTION_LINES = 100
IMPORTERS = {"import_module", "__import__"}


def _modules():
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(PKG).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _dynamic_target(call):
    """The ``bayes_mpem`` module an ``importlib.import_module(...)`` call names, or None.

    A literal name counts, and so does the literal head of an f-string
    (``f"bayes_mpem.report{x}"``); ``f"{__name__}.{x}"`` stays inside the caller."""
    func = call.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name not in IMPORTERS or not call.args:
        return None
    arg = call.args[0]
    if isinstance(arg, ast.JoinedStr) and arg.values and isinstance(arg.values[0], ast.Constant):
        arg = arg.values[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        text = arg.value
        if text == "bayes_mpem" or text.startswith("bayes_mpem."):
            return text[len("bayes_mpem."):].rstrip(".")
    return None


def _imports(name, path, *, top_level_only, source=None):
    """``(module imported, names imported, line)`` for each import of ``name`` inside the
    package: relative and absolute ``from`` imports and ``importlib`` calls."""
    tree = ast.parse(path.read_text() if source is None else source)
    is_pkg = path.name == "__init__.py"
    nodes = tree.body if top_level_only else ast.walk(tree)
    out = []
    for node in nodes:
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            base = name.split(".") if is_pkg else name.split(".")[:-1]
            if node.level > 1:
                base = base[:len(base) - (node.level - 1)]
            target = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{target}.{alias.name}" if target else alias.name
                out.append((sub if sub in MODULES else target, alias.name, node.lineno))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("bayes_mpem"):
            out.append((node.module[len("bayes_mpem."):], None, node.lineno))
        elif isinstance(node, ast.Call) and (target := _dynamic_target(node)) is not None:
            out.append((target, None, node.lineno))
    return out


def _part(module):
    return module.split(".")[0] if module else ""


def _layer_violations(name, path, source=None):
    bad = []
    for target, _, line in _imports(name, path, top_level_only=False, source=source):
        src, dst = _part(name), _part(target)
        if not dst or src == dst:
            continue
        if LAYER[dst] > LAYER[src] or (LAYER[dst] == LAYER[src] and {src, dst} <= WINGS):
            bad.append(f"{path.relative_to(PKG)}:{line} imports {target}")
        elif LAYER[dst] == LAYER[src]:
            bad.append(f"{path.relative_to(PKG)}:{line} imports {target} (same layer)")
    return bad


def test_imports_point_down_and_wings_stay_apart():
    # the package __init__ gathers the public API from everywhere
    bad = [b for name, path in MODULES.items() if name for b in _layer_violations(name, path)]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("planted", [
    'import importlib\nreport = importlib.import_module("bayes_mpem.report")\n',
    'from importlib import import_module\nmod = import_module(f"bayes_mpem.cli.{x}")\n',
    'cli = __import__("bayes_mpem.cli")\n',
])
def test_an_upward_importlib_call_is_caught(planted):
    """The layer rule reads ``importlib`` calls too: a planted one in ``lbl`` is refused."""
    path = MODULES["lbl.survey.fitting"]
    assert not _layer_violations("lbl.survey.fitting", path)
    assert _layer_violations("lbl.survey.fitting", path, source=path.read_text() + planted)


def test_no_import_cycle():
    graph = {name: {t for t, _, _ in _imports(name, path, top_level_only=False)
                    if t in MODULES and t != name and not name.startswith(t + ".")
                    and t != ""}
             for name, path in MODULES.items() if name}
    # a package __init__ re-exporting its own submodules is not a cycle
    state, stack, cycles = {}, [], []

    def visit(v):
        state[v] = 1
        stack.append(v)
        for w in graph.get(v, ()):
            if state.get(w) == 1:
                cycles.append(stack[stack.index(w):] + [w])
            elif w not in state:
                visit(w)
        stack.pop()
        state[v] = 2

    for v in graph:
        if v not in state:
            visit(v)
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)


def test_no_private_name_crosses_a_module():
    bad = [f"{path.relative_to(PKG)}:{line} imports {alias} from {target}"
           for name, path in MODULES.items()
           for target, alias, line in _imports(name, path, top_level_only=False)
           if alias and alias.startswith("_") and not alias.startswith("__")
           and alias not in MODULES.get(target, Path()).stem]
    assert not bad, "\n".join(bad)


def _code_lines(node, source_lines):
    """Lines of a function that are neither blank, comments nor its docstring."""
    doc = ast.get_docstring(node, clean=False)
    skip = set()
    if doc is not None:
        d = node.body[0]
        skip = set(range(d.lineno, d.end_lineno + 1))
    n = 0
    for i in range(node.lineno, node.end_lineno + 1):
        text = source_lines[i - 1].strip()
        if i not in skip and text and not text.startswith("#"):
            n += 1
    return n


def test_functions_are_short_or_say_why():
    long = []
    for _, path in MODULES.items():
        source = path.read_text()
        lines = source.splitlines()
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = _code_lines(node, lines)
                above = lines[node.lineno - 2] if node.lineno > 1 else ""
                if n > MAX_FUNCTION_LINES and "long function:" not in above:
                    long.append(f"{path.relative_to(PKG)}:{node.lineno} {node.name} ({n} lines)")
    assert not long, "\n".join(long)


def test_every_module_is_in_the_architecture_page():
    """docs/architecture.md says in one line what each module of the tree holds."""
    page = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
    if not page.is_file():
        pytest.skip("not a source checkout")
    text = page.read_text()
    missing = [str(p.relative_to(PKG)) for name, p in MODULES.items()
               if p.name != "__init__.py" and str(p.relative_to(PKG)) not in text]
    assert not missing, missing


def _public_names():
    """``(package, name)`` of every name in ``__all__`` of the package and its subpackages."""
    out = []
    for name, path in MODULES.items():
        if path.name != "__init__.py":
            continue
        for node in ast.parse(path.read_text()).body:
            if (isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__"
                                                     for t in node.targets)):
                out += [(name, n) for n in ast.literal_eval(node.value)]
    return out


def test_the_api_reference_is_the_public_surface():
    """docs/api.md documents every public function and class (``__all__`` of the package and
    of each subpackage, or the module defining it), and no private module."""
    api = Path(__file__).resolve().parents[1] / "docs" / "api.md"
    if not api.is_file():
        pytest.skip("not a source checkout")
    listed = {line.strip() for line in api.read_text().splitlines()}
    top = {n for package, n in _public_names() if not package}  # listed by their own name
    missing = []
    for package, name in _public_names():
        if name.startswith("_") or name.isupper() or _part(package) == "cli":
            continue  # constants and the version are data; the command line is cli.md's
        dotted = f"{package}.{name}" if package else name
        defined = getattr(importlib.import_module(".".join(filter(None, ("bayes_mpem",
                                                                         package)))), name)
        module = defined.__module__.removeprefix("bayes_mpem.")
        if not ({dotted, module} & listed or (name in top and name in listed)):
            missing.append(dotted)
    assert not missing, missing
    shown = [name for name in MODULES
             if any(part.startswith("_") for part in name.split(".")) and name in listed]
    assert not shown, shown


def test_results_never_import_plots():
    bad = [f"{p.relative_to(PKG)}:{line} imports {t}"
           for name, p in MODULES.items()
           if _part(name) in {"io", "acoustics", "mixture", "mcmc", "lbl", "survey_in"}
           for t, _, line in _imports(name, p, top_level_only=False)
           if _part(t) in {"plots", "report", "cli"}]
    assert not bad, "\n".join(bad)


def test_importing_the_package_warns_nothing():
    code = ("import warnings, importlib, sys; warnings.simplefilter('error'); "
            "import bayes_mpem; import bayes_mpem.cli")
    import subprocess
    import sys

    subprocess.run([sys.executable, "-c", code], check=True)


def test_import_and_help_load_no_heavy_library():
    """``import bayes_mpem`` and every ``--help`` import no numpy, pandas, SciPy, emcee, ArviZ
    or matplotlib (the public names and the sub-commands load on first use, PEP 562), so
    ``bayes-mpem --help`` answers at once (benchmarks/bench_startup.py times it)."""
    code = (
        "import sys, warnings; warnings.simplefilter('error')\n"
        "import bayes_mpem\n"
        "from bayes_mpem.cli.parser import COMMANDS, build_parser\n"
        "parser = build_parser(); parser.format_help()\n"
        "sub = parser._subparsers._group_actions[0].choices\n"
        "assert set(sub) == set(COMMANDS), (set(sub), set(COMMANDS))\n"
        "[p.format_help() for p in sub.values()]\n"
        "heavy = {'numpy', 'pandas', 'scipy', 'emcee', 'arviz_base', 'xarray', 'matplotlib'}\n"
        "assert not heavy & set(sys.modules), heavy & set(sys.modules)\n"
        "from bayes_mpem import fit, SurveyFit\n"
        "assert fit.__module__ == 'bayes_mpem.lbl.survey.fitting' and 'numpy' in sys.modules\n"
        "assert set(bayes_mpem.__all__) <= set(dir(bayes_mpem))\n"
        "assert all(getattr(bayes_mpem, n) is not None for n in bayes_mpem.__all__)\n")
    import subprocess
    import sys

    subprocess.run([sys.executable, "-c", code], check=True)
