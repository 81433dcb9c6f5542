"""No job-kind name outside its kind's own modules, the registry and generated files.

A kind is one module that registers itself (``fieldrx_edge/jobkinds/kinds/<name>.py``,
with its server hooks in ``fieldrx/jobkinds/<name>.py`` and its screens' parts in
``frontend/src/kinds/<name>.tsx``); everything else asks the registry. A kind's name
written anywhere else is a list or a branch that the next kind would have to edit, so
this test fails on it, naming the file and line.
"""

from __future__ import annotations

import re
from pathlib import Path

from fieldrx_edge.jobkinds.registry import names

ROOT = Path(__file__).resolve().parents[1]
ROOTS = ("backend/fieldrx", "edge_agent/fieldrx_edge", "frontend/src")
SUFFIXES = (".py", ".ts", ".tsx", ".js", ".mjs", ".html", ".json")
# a kind's own modules: these folders hold one file per kind, named after it
KIND_DIRS = (
    "edge_agent/fieldrx_edge/jobkinds/kinds",
    "backend/fieldrx/jobkinds",
    "frontend/src/kinds",
)
# the registry (the default kind) and files written by scripts/gen-api.sh
ALLOWED = (
    "edge_agent/fieldrx_edge/jobkinds/registry.py",
    "frontend/src/api/openapi.json",
    "frontend/src/api/generated/",
)


def _allowed(rel: str, kind: str) -> bool:
    if rel.startswith(ALLOWED) or re.search(r"\.test\.(ts|tsx)$", rel):
        return True  # vitest files are tests, as tests/ is
    path = Path(rel)
    return str(path.parent) in KIND_DIRS and path.stem == kind


def literals(root: Path = ROOT) -> list[str]:
    """``path:line: kind`` for every kind name outside where it may be written."""
    kinds = names()
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, kinds)) + r")\b")
    out: list[str] = []
    for base in ROOTS:
        for path in sorted((root / base).rglob("*")):
            if path.suffix not in SUFFIXES or not path.is_file():
                continue
            rel = path.relative_to(root).as_posix()
            if "/node_modules/" in rel or "/dist/" in rel:
                continue
            for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                for m in pattern.finditer(line):
                    if not _allowed(rel, m.group(1)):
                        out.append(f"{rel}:{n}: {m.group(1)}")
    return out


def test_kind_names_only_in_their_modules() -> None:
    found = literals()
    assert found == [], "job-kind names outside their kind's modules:\n" + "\n".join(found)


def test_the_check_sees_a_stray_name(tmp_path: Path) -> None:
    """The check itself: a name in an ordinary module is found, in its own module not."""
    kind = names()[0]
    ordinary = tmp_path / "backend/fieldrx/api/x.py"
    own = tmp_path / f"backend/fieldrx/jobkinds/{kind}.py"
    for p in (ordinary, own):
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(f'if kind == "{kind}":\n    pass\n')
    assert literals(tmp_path) == [f"backend/fieldrx/api/x.py:1: {kind}"]
