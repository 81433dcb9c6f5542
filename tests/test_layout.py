"""Every test file sits where its module's path says (docs/architecture.md, Conventions).

A module's tests are found by its path: `backend/fieldrx/<pkg>/<mod>.py` is tested in
`tests/<pkg>/test_<mod>[_<aspect>].py`, `edge_agent/fieldrx_edge/<pkg>/<mod>.py` in
`tests/edge/<pkg>/test_<mod>[_<aspect>].py`. A test file named for something that does not
exist, or in a folder that mirrors no package, would leave the next reader looking in the
wrong place, so it fails here rather than in review.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
SERVER = ROOT / "backend" / "fieldrx"
EDGE = ROOT / "edge_agent" / "fieldrx_edge"
# whole-system tests and shared support: not one module's, named for what they prove
EXEMPT = ("system", "support", "e2e")
# checks of the repository itself, at the top of tests/
REPO_CHECKS = {
    "test_docs",
    "test_import_cycles",
    "test_no_private_imports",
    "test_layout",
    "test_module_size",
}


def _names(package: Path) -> set[str]:
    """The modules and sub-packages of a package folder, by the name a test starts with."""
    mods = {p.stem for p in package.glob("*.py") if p.stem != "__init__"}
    subs = {p.name for p in package.iterdir() if p.is_dir() and any(p.glob("*.py"))}
    return mods | subs


def _package(folders: tuple[str, ...]) -> Path:
    if folders[:1] == ("edge",):
        return EDGE.joinpath(*folders[1:])
    return SERVER.joinpath(*folders)


def misplaced(files: Iterable[Path]) -> list[str]:
    """The test files (paths relative to tests/) that are not where the layout says."""
    wrong = []
    for rel in files:
        folders, stem = rel.parts[:-1], rel.stem
        if folders[:1] and folders[0] in EXEMPT:
            continue
        if not folders and stem in REPO_CHECKS:
            continue
        package = _package(folders)
        if not package.is_dir() or not any(package.glob("*.py")):
            wrong.append(f"{rel}: no package {package.relative_to(ROOT)} to mirror")
            continue
        names = _names(package)
        if not any(stem == f"test_{n}" or stem.startswith(f"test_{n}_") for n in names):
            wrong.append(
                f"{rel}: names no module or sub-package of {package.relative_to(ROOT)}"
            )
    return wrong


def _test_files() -> list[Path]:
    return sorted(
        p.relative_to(TESTS)
        for p in TESTS.rglob("test_*.py")
        if "node_modules" not in p.parts and "__pycache__" not in p.parts
    )


def test_every_test_file_mirrors_a_module() -> None:
    assert misplaced(_test_files()) == []


def test_the_checker_finds_a_misplaced_file() -> None:
    bad = [
        Path("control/test_control_pid.py"),  # a feature folder, not a package
        Path("api/test_field_import.py"),  # api has fields.py, no field_import.py
        Path("edge/test_wire.py"),  # the edge has no module or sub-package "wire"
        Path("test_helpers.py"),  # no top-level module "helpers"
    ]
    good = [
        Path("edge/control/test_pid_incremental.py"),
        Path("edge/test_gnss.py"),
        Path("geo/test_coverage_properties.py"),
        Path("test_demo.py"),
        Path("system/test_attack_suite.py"),
    ]
    assert [m.split(":")[0] for m in misplaced(bad + good)] == [str(p) for p in bad]
