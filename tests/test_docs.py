"""The docs name only what exists: links resolve, paths exist, cited functions are defined.

docs/architecture.md is the map a new engineer reads first and docs/science.md says which
function implements each equation; a rename that leaves them pointing at nothing would
send the reader to code that is not there, so the check runs with the unit tests.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("README.md", "docs/architecture.md", "docs/science.md", "docs/scale.md")
# where a short path in the docs ("geo/grid.py", "jobs.py") is looked up
BASES = ("", "backend/fieldrx/", "edge_agent/fieldrx_edge/", "frontend/src/")
FILE_TOKEN = re.compile(r"`([A-Za-z0-9_./-]+\.(?:py|ts|tsx|sh|conf|mjs|md|json|ini|yml))`")
# "`module.py` `name`" and "`module.py` `A`, `B`": each name defined in that module
CITATION = re.compile(r"`([A-Za-z0-9_/]+\.py)`((?: `[A-Za-z_][A-Za-z0-9_.]*`,?)+)")


def _find(token: str) -> Path | None:
    for base in BASES:
        path = ROOT / base / token
        if path.exists():
            return path
    hits = [p for b in BASES[1:] for p in (ROOT / b).rglob(token) if p.is_file()]
    return hits[0] if len(hits) == 1 else None


def test_links_resolve() -> None:
    broken = []
    for page in PAGES:
        text = (ROOT / page).read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if not target.startswith("http") and not (ROOT / page).parent.joinpath(target).exists():
                broken.append(f"{page}: {target}")
    assert broken == []


def test_named_files_exist() -> None:
    missing = []
    for page in PAGES:
        for token in FILE_TOKEN.findall((ROOT / page).read_text(encoding="utf-8")):
            if "<" not in token and _find(token) is None:
                missing.append(f"{page}: {token}")
    assert missing == []


def test_cited_functions_are_defined() -> None:
    undefined = []
    for page in PAGES:
        for module, names in CITATION.findall((ROOT / page).read_text(encoding="utf-8")):
            path = _find(module)
            if path is None:
                undefined.append(f"{page}: {module} (no such module)")
                continue
            source = path.read_text(encoding="utf-8")
            for name in re.findall(r"`([A-Za-z_][A-Za-z0-9_.]*)`", names):
                last = name.split(".")[-1]
                pattern = rf"(def|class)\s+{last}\b|^\s*{last}\s*(:[^=\n]*)?="
                if not re.search(pattern, source, re.M):
                    undefined.append(f"{page}: {module} {name}")
    assert undefined == []
