"""The edge agent installs and imports on its own, without any server dependency."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_edge_agent_installs_without_server_deps(tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py = venv / "bin" / "python"
    subprocess.run(
        [
            str(py),
            "-m",
            "pip",
            "install",
            "-q",
            "--disable-pip-version-check",
            "-c",
            str(ROOT / "requirements.lock"),
            str(ROOT / "edge_agent"),
        ],
        check=True,
    )
    code = (
        "import importlib.util, sys, fieldrx_edge, fieldrx_edge.protocol, fieldrx_edge.metering\n"
        "mods = ['fastapi', 'sqlalchemy', 'psycopg', 'geoalchemy2', 'shapely', 'fieldrx']\n"
        "present = [m for m in mods if importlib.util.find_spec(m)]\n"
        "assert not present, present\n"
        "print('ok')\n"
    )
    out = subprocess.run([str(py), "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_edge_package_never_imports_server() -> None:
    """Static check: no module of fieldrx_edge imports the server or its libraries."""
    banned = (
        "fieldrx.",
        "import fieldrx\n",
        "fastapi",
        "sqlalchemy",
        "psycopg",
        "shapely",
        "pyproj",
        "geoalchemy2",
    )
    offenders = []
    for path in (ROOT / "edge_agent" / "fieldrx_edge").rglob("*.py"):
        text = path.read_text()
        for line in text.splitlines():
            s = line.strip()
            if s.startswith(("import ", "from ")) and any(b.strip() in s for b in banned):
                offenders.append(f"{path.relative_to(ROOT)}: {s}")
    assert not offenders, offenders
