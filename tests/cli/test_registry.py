"""The command table is the one list of the commands: everything else is drawn from it."""

import ast
from pathlib import Path

import pytest

import bayes_mpem
from bayes_mpem.cli.parser import UNIT_COMMANDS, build_parser
from bayes_mpem.commands import COMMANDS, load, with_results

SRC = Path(bayes_mpem.__file__).resolve().parent


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_name_of_an_entry_loads(name):
    c = COMMANDS[name]
    assert callable(load(f"{c.module}:cmd_{name}")) and callable(load(c.options))
    if c.result is not None:
        kind = load(c.result)
        assert callable(kind.write) and callable(kind.read) and callable(load(c.figures))
        assert c.palette  # a command with figures takes --palette
    if c.batch is not None:
        assert all(callable(load(n)) for n in (c.batch.kwargs, c.batch.run, c.batch.rows))


def test_the_parser_is_drawn_from_the_table():
    sub = build_parser().parse_args(["fit", "p", "--beacons", "b", "--out", "o"]).subparsers
    assert list(sub) == list(COMMANDS)
    for name, p in sub.items():
        options = {s for a in p._actions for s in a.option_strings}
        assert ("--palette" in options) == COMMANDS[name].palette, name
        assert ("--travel-time" in options) == (name in UNIT_COMMANDS), name
    assert set(UNIT_COMMANDS) == {n for n, c in COMMANDS.items() if c.units}
    assert set(with_results()) <= set(COMMANDS) - {"plot", "demo", "stream", "batch"}


def _name_lists(tree):
    """Tuples, lists, sets and dict keys: two or more string literals, all command names."""
    for node in ast.walk(tree):
        items = (node.elts if isinstance(node, (ast.Tuple, ast.List, ast.Set)) else
                 node.keys if isinstance(node, ast.Dict) else [])
        words = [e.value for e in items if isinstance(e, ast.Constant)]
        if len(items) >= 2 and len(words) == len(items) and all(w in COMMANDS for w in words):
            yield node.lineno, words


def test_no_second_list_of_command_names():
    """Outside ``commands.py``, no tuple, list or set of command names (the bug it prevents:
    one list updated, another forgotten); a planted one is found."""
    found = [f"{p.relative_to(SRC)}:{line} {words}"
             for p in sorted(SRC.rglob("*.py")) if p.name != "commands.py" or p.parent != SRC
             for line, words in _name_lists(ast.parse(p.read_text()))]
    assert not found, "\n".join(found)
    assert list(_name_lists(ast.parse('BATCH = ("fit", "sample")\n')))


def test_no_folder_kind_hides_another():
    """Two kinds marked by one file: neither's keys are a subset of the other's, so a folder
    matches one kind whatever the table's order."""
    kinds = list(with_results().values())
    for a in kinds:
        for b in kinds:
            if a is not b and a.folder[0] == b.folder[0]:
                assert not set(a.folder[1]) <= set(b.folder[1]), (a.result, b.result)
