"""Check the built API reference: every generated page shows its docstrings.

Reads the HTML that ``sphinx-build -b html docs docs/_build/html`` writes under
``generated/`` and fails when a page

* shows a directive as text (``.. autofunction::``: the stub was not parsed as
  reStructuredText, which the ``-W`` build does not catch), or documents nothing;
* documents a function or method that takes arguments without a *Parameters*
  section, or a class whose signature has arguments without a *Parameters* or
  *Attributes* section (numpydoc renders each as a field of the object's description);
* documents a function, method or class with an empty description.

Run after the docs build (``.ci/run`` does); exits 1 and lists the problems::

    python docs/check_api_pages.py [docs/_build/html]

``tests/test_api_docs.py`` tests the checker; ``pytest --with-docs-build`` also builds the API
pages alone and runs the same check.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path

#: objects whose description must show their documentation
CHECKED = ("function", "method", "class", "exception")
VOID = {"br", "img", "input", "link", "meta", "hr", "wbr", "col", "area", "base", "source"}


class _Node:
    def __init__(self, tag: str, attrs: dict, parent: _Node | None) -> None:
        self.tag, self.attrs, self.parent = tag, attrs, parent
        self.children: list[_Node | str] = []

    @property
    def classes(self) -> list[str]:
        return (self.attrs.get("class") or "").split()

    def text(self) -> str:
        return "".join(c if isinstance(c, str) else c.text() for c in self.children)

    def find_all(self, pred, *, stop=None):
        """Descendants matching ``pred``, not looking inside nodes matching ``stop``."""
        for c in self.children:
            if isinstance(c, _Node):
                if pred(c):
                    yield c
                if stop is None or not stop(c):
                    yield from c.find_all(pred, stop=stop)


class _TreeBuilder(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.root = self.cur = _Node("root", {}, None)

    def handle_starttag(self, tag, attrs):
        node = _Node(tag, dict(attrs), self.cur)
        self.cur.children.append(node)
        if tag not in VOID:
            self.cur = node

    def handle_endtag(self, tag):
        node = self.cur
        while node is not self.root and node.tag != tag:  # tolerate unclosed tags
            node = node.parent
        if node is not self.root:
            self.cur = node.parent

    def handle_data(self, data):
        self.cur.children.append(data)


def _parse(path: Path) -> _Node:
    builder = _TreeBuilder()
    builder.feed(path.read_text(encoding="utf-8"))
    return builder.root


def _is_object(node) -> bool:
    return node.tag == "dl" and "py" in node.classes


def _fields(dd) -> set[str]:
    """Names of the numpydoc fields (Parameters, Returns, ...) of one description."""
    return {f.text().strip().rstrip(":")
            for f in dd.find_all(lambda n: n.tag == "dt" and any(c.startswith("field-")
                                                                 for c in n.classes),
                                 stop=_is_object)}


def _arguments(dt) -> list[str]:
    """Argument names in a signature (the bare ``*`` and ``/`` markers left out)."""
    params = dt.find_all(lambda n: n.tag == "em" and "sig-param" in n.classes)
    return [t for t in (p.text().strip() for p in params) if t not in ("*", "/", "")]


def check_object(dl) -> list[str]:
    """Problems of one object description (``<dl class="py function">`` and the like).

    Parameters
    ----------
    dl : _Node
        The description list of one documented object.

    Returns
    -------
    list of str
        Empty when the object shows what it must.
    """
    kind = next(c for c in dl.classes if c != "py")
    if kind not in CHECKED:
        return []
    dt = next(c for c in dl.children if isinstance(c, _Node) and c.tag == "dt")
    dd = next(c for c in dl.children if isinstance(c, _Node) and c.tag == "dd")
    name = dt.attrs.get("id") or dt.text().strip().split("(")[0]
    own_text = "".join(c if isinstance(c, str) else ("" if _is_object(c) else c.text())
                       for c in dd.children).strip()
    if not own_text:
        return [f"{kind} {name}: empty description (no docstring shown)"]
    args, fields = _arguments(dt), _fields(dd)
    if kind in ("function", "method") and args and "Parameters" not in fields:
        return [f"{kind} {name}({', '.join(args)}): no Parameters section"]
    if kind in ("class", "exception") and args and not fields & {"Parameters", "Attributes"}:
        return [f"{kind} {name}({', '.join(args)}): no Parameters or Attributes section"]
    return []


def check_page(path: Path) -> list[str]:
    """Problems of one generated API page.

    Parameters
    ----------
    path : pathlib.Path
        An HTML page under ``generated/``.

    Returns
    -------
    list of str
        One line per problem, each starting with the page's name.
    """
    root = _parse(path)
    body = next(root.find_all(lambda n: n.tag == "div" and "body" in n.classes), root)
    text = body.text()
    problems = [f"raw directive shown as text: {d!r}" for d in
                (".. auto", ".. currentmodule", ".. automodule") if d in text]
    objects = list(body.find_all(_is_object))
    is_module = path.stem in _module_names(path)
    if not objects and not is_module:
        problems.append("documents no object")
    for dl in objects:
        problems += check_object(dl)
    return [f"{path.name}: {p}" for p in problems]


def _module_names(path: Path) -> set[str]:
    """Page names of modules: their page has a module index entry (``module-<name>`` id)."""
    html = path.read_text(encoding="utf-8")
    return {path.stem} if f'id="module-{path.stem}"' in html else set()


def check_html(html_dir) -> list[str]:
    """Problems of every page under ``html_dir/generated``.

    Parameters
    ----------
    html_dir : str or pathlib.Path
        The HTML output folder of the docs build.

    Returns
    -------
    list of str
        Empty when every page is complete.

    Raises
    ------
    FileNotFoundError
        When the folder has no generated API pages.
    """
    pages = sorted(Path(html_dir, "generated").glob("*.html"))
    if not pages:
        raise FileNotFoundError(f"no generated API pages under {Path(html_dir, 'generated')}")
    return [p for page in pages for p in check_page(page)]


def main(argv=None) -> int:
    """Check the pages; print the problems; 0 when none, 1 otherwise."""
    argv = sys.argv[1:] if argv is None else argv
    html_dir = Path(argv[0] if argv else "docs/_build/html")
    problems = check_html(html_dir)
    n = len(list((html_dir / "generated").glob("*.html")))
    for p in problems:
        print(p)
    print(f"{n} API pages checked, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
