"""No module imports or reaches into another module's private (_underscore) names.

Checked with ast over backend/, edge_agent/ and bench/:

* ``from m import _name`` and ``import m`` + ``m._name`` for any project module;
* ``obj._name`` on something other than ``self`` / ``cls`` where ``_name`` is not
  defined (as a function, class, assignment or attribute) in the same module: a
  private field of another module's object (``CellLocator._items``).

Names the Python data model or a library documents as public despite the
underscore (namedtuple's ``_replace``/``_asdict``/``_fields``, SQLAlchemy's
``Row._mapping``, ``sys._getframe``, argparse's ``_SubParsersAction``) are allowed.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREES = ("backend", "edge_agent", "bench")
ALLOWED_ATTRS = {"_replace", "_asdict", "_fields", "_make", "_mapping", "_getframe", "_exit"}
# argparse has no public name for the type add_subparsers() returns
ALLOWED_ATTRS |= {"_SubParsersAction"}


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _defined_here(tree: ast.AST) -> set[str]:
    """Private names this module defines itself (so using them is not crossing a module)."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            out.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            out.add(node.id)
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.ctx, ast.Store)
            and isinstance(node.value, ast.Name)
            and node.value.id in ("self", "cls")
        ):
            out.add(node.attr)  # its own objects' fields (not another module's object's)
        elif isinstance(node, ast.arg):
            out.add(node.arg)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            out.add(node.target.id)
    return {n for n in out if _private(n)}


def violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    own = _defined_here(tree)
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            for a in node.names:
                if _private(a.name):
                    out.append(f"{rel}:{node.lineno}: from {node.module} import {a.name}")
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            base = node.value
            if isinstance(base, ast.Name) and base.id in ("self", "cls"):
                continue
            if node.attr in own or node.attr in ALLOWED_ATTRS:
                continue
            out.append(f"{rel}:{node.lineno}: .{node.attr} of another module's object")
    return out


def test_no_module_uses_another_modules_private_names() -> None:
    found: list[str] = []
    for tree in TREES:
        for path in sorted((ROOT / tree).rglob("*.py")):
            if "node_modules" in path.parts or ".venv" in path.parts:
                continue
            found += violations(path)
    assert not found, "private names crossing modules:\n" + "\n".join(found)


def test_the_checker_finds_a_crossing(tmp_path: Path) -> None:
    """The rule bites (a test that cannot fail is a defect)."""
    bad = tmp_path / "probe.py"
    bad.write_text(
        "from fieldrx_edge.locate import _in_quad\n\n\ndef f(loc):\n    return loc._items\n"
    )
    v = violations(bad)
    assert len(v) == 2, v
