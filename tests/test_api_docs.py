"""The built API reference shows the docstrings (``docs/check_api_pages.py``).

CI builds the documentation (``.ci/run``: ``sphinx-build -W``) and runs
``docs/check_api_pages.py`` on it: every generated HTML page, no directive shown as text,
every function or method with arguments has its Parameters section, every class its
Parameters or Attributes. The suite tests that the checker catches what it must; with
``pytest --with-docs-build`` (and the ``docs`` extra) it also builds ``docs/api.md`` alone
(its generated stubs, with the real ``conf.py`` and templates, notebooks not executed) and
runs the check, a 30 s build that CI's docs step makes anyway.
"""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _checker():
    spec = importlib.util.spec_from_file_location("check_api_pages",
                                                  DOCS / "check_api_pages.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_checker_catches_raw_directives_and_missing_parameters(tmp_path):
    gen = tmp_path / "generated"
    gen.mkdir()
    page = ('<div class="body"><dl class="py function"><dt id="m.f">f(<em class="sig-param">'
            'x</em>)</dt><dd><p>Summary.</p>{fields}</dd></dl></div>'
            '<div class="sphinxsidebar"></div>')
    fields = ('<dl class="field-list"><dt class="field-odd">Parameters<span>:</span></dt>'
              '<dd>x : float</dd></dl>')
    (gen / "m.f.html").write_text(page.format(fields=fields))
    check = _checker()
    assert check.check_html(tmp_path) == []
    (gen / "m.f.html").write_text(page.format(fields=""))
    assert check.check_html(tmp_path) == ["m.f.html: function m.f(x): no Parameters section"]
    (gen / "m.f.html").write_text('<div class="body"><p>.. autofunction:: f</p></div>')
    assert any("raw directive" in p for p in check.check_html(tmp_path))


def test_ci_runs_the_check_on_the_built_site():
    ci = (DOCS.parent / ".ci" / "run").read_text()
    build = ci.index("sphinx-build -W -b html docs docs/_build/html")
    assert ci.index("docs/check_api_pages.py docs/_build/html") > build
    assert "set -euo pipefail" in ci


@pytest.mark.docs_build
def test_generated_api_pages_show_the_docstrings(tmp_path):
    for name in ("sphinx", "myst_nb", "numpydoc"):
        pytest.importorskip(name, reason="the docs extra is not installed")
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy2(DOCS / "conf.py", src / "conf.py")
    shutil.copytree(DOCS / "_templates", src / "_templates")
    shutil.copy2(DOCS / "api.md", src / "index.md")
    out = tmp_path / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-q", "-W", "-D",
         "nb_execution_mode=off", "-D", "suppress_warnings=myst.xref_missing,myst.header",
         str(src), str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    problems = _checker().check_html(out)
    assert not problems, "\n".join(problems)
