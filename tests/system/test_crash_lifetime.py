"""``kill -9`` of the API during a plan, an ISOXML import and an imagery conversion: its
heavy children die with it (within 10 s), nothing is committed afterwards, and the next
start removes every file they left (spooled uploads, received imagery, partial COGs)."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
import shapely
from sqlalchemy import text

from tests.fleet.procs import BIN, Proc, free_port
from tests.imagery.rasters import X0, Y0, field_geojson, write_tiff
from tests.support import feature
from tests.support.plans import rectangle

API = "/api/v1"
pytestmark = pytest.mark.slow


def _proc_tree(root: int) -> dict[int, str]:
    """Live descendants of ``root``: pid -> command line (zombies count as ended)."""
    parent: dict[int, int] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z":
            parent[int(d.name)] = int(fields[1])
    out: dict[int, str] = {}
    frontier = [root]
    while frontier:
        p = frontier.pop()
        for child, pp in parent.items():
            if pp == p and child not in out:
                try:
                    out[child] = (
                        Path(f"/proc/{child}/cmdline").read_bytes().decode(errors="replace")
                    )
                except OSError:
                    continue
                frontier.append(child)
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2 :].split()[0] != "Z"


def _big_taskdata() -> bytes:
    """A TASKDATA zip with a 4 km x 4 km (1,600 ha) prescribed field."""
    from fieldrx.agronomy.cells import CellTable
    from fieldrx.formats.isoxml import write_isoxml_grid

    c = CellTable.rectangle(32649, 624000.0, 3556000.0, 2, 2, 2000.0, 2000.0).with_rates(
        np.array([100.0, 200.0, 300.0, 400.0])
    )
    return write_isoxml_grid(c, "big", shapely.union_all(c.polygons_wgs84()), grid_cell_m=500.0)


def _files(d: Path) -> list[Path]:
    return sorted(p for p in d.rglob("*") if p.is_file() or p.name.startswith(".work-"))


def _start(env: dict[str, str], port: int) -> Proc:
    proc = Proc([str(BIN / "fieldrx"), "serve", "--port", str(port)], env)
    proc.wait_for("Uvicorn running on", timeout=120)
    return proc


def test_kill_9_leaves_no_child_no_commit_no_file(database_url, org, db, tmp_path) -> None:  # noqa: ANN001
    imagery_dir, tmp = tmp_path / "imagery", tmp_path / "tmp"
    tmp.mkdir()
    env = {
        "DATABASE_URL": database_url,
        "FIELDRX_IMAGERY_DIR": str(imagery_dir),
        "TMPDIR": str(tmp),
        "FIELDRX_HEAVY_WORKERS": "3",
        "FIELDRX_PLAN_TIME_LIMIT_S": "600",
        "FIELDRX_IMAGERY_MAX_EXPANSION": "1e12",  # let the sparse raster convert (slowly)
    }
    h = org.headers()
    port = free_port()
    api = f"http://127.0.0.1:{port}"
    proc = _start(env, port)
    n_fields = db.scalar(
        text("SELECT count(*) FROM fields WHERE organisation_id = :o"), {"o": org.id}
    )
    try:
        with httpx.Client(base_url=api, headers=h, timeout=60) as c:
            big = c.post(f"{API}/fields", json=feature(rectangle(112.30, 32.10, 4000, 4000)))
            img_field = c.post(f"{API}/fields", json=feature(field_geojson()))
            assert big.status_code == img_field.status_code == 201
            zip_bytes = _big_taskdata()
            pre = c.post(
                f"{API}/imports/isoxml", files={"files": ("TASKDATA.zip", zip_bytes)}, timeout=120
            )
            assert pre.status_code == 200, (pre.text, proc.lines[-40:])
        sha = pre.json()["sha256"]
        raster = write_tiff(
            tmp_path / "sparse.tif",
            bounds=(X0, Y0, X0 + 2000, Y0 + 2000),
            res=0.1,
            skip_write=True,
        )
        errors: list[str] = []

        def call(method: str, url: str, **kw: object) -> None:
            try:
                httpx.request(method, api + url, headers=h, timeout=600, **kw)
            except httpx.HTTPError as exc:
                errors.append(repr(exc))

        raster_bytes = raster.read_bytes()
        calls = [
            ("POST", f"{API}/fields/{big.json()['id']}/plans", {"json": {"swath_width_m": 1.0}}),
            (
                "POST",
                f"{API}/imports/isoxml?confirm={sha}&swath_width_m=1&cell_length_m=5",
                {"files": {"files": ("TASKDATA.zip", zip_bytes)}},
            ),
            (
                "POST",
                f"{API}/fields/{img_field.json()['id']}/imagery?background=false",
                {"files": {"file": ("s.tif", raster_bytes)}, "data": {"kind": "orthophoto"}},
            ),
        ]
        threads = [threading.Thread(target=call, args=(m, u), kwargs=kw) for m, u, kw in calls]
        for t in threads:
            t.start()
        # ready: the forkserver with two working children (plan, import) and the converter
        deadline = time.monotonic() + 180
        while True:
            tree = _proc_tree(proc.p.pid)
            forked = sum("forkserver" in cmd for cmd in tree.values())
            spawned = sum("spawn_main" in cmd for cmd in tree.values())
            if forked >= 3 and spawned >= 1:
                break
            assert time.monotonic() < deadline, (tree, proc.lines[-20:])
            time.sleep(0.2)
        time.sleep(1.0)  # let them get into their work
        tree = _proc_tree(proc.p.pid)
        assert _files(imagery_dir) and list(tmp.glob("fieldrx-upload-*"))  # work in flight
        os.kill(proc.p.pid, signal.SIGKILL)
        proc.p.wait(30)
        t0 = time.monotonic()
        while [p for p in tree if _alive(p)] and time.monotonic() - t0 < 10:
            time.sleep(0.1)
        left = {p: tree[p][:120] for p in tree if _alive(p)}
        assert not left, f"children alive 10 s after kill -9 of the API: {left}"
        for t in threads:
            t.join(30)
        time.sleep(2.0)  # a child that survived would commit now
        assert (
            db.scalar(
                text("SELECT count(*) FROM plans WHERE field_id = :f"), {"f": big.json()["id"]}
            )
            == 0
        )
        assert (
            db.scalar(text("SELECT count(*) FROM fields WHERE organisation_id = :o"), {"o": org.id})
            == n_fields + 2
        )  # the two made above; nothing of the import
        assert (
            db.scalar(
                text("SELECT count(*) FROM imagery WHERE organisation_id = :o"), {"o": org.id}
            )
            == 0
        )
        # the next start removes what the killed server left
        proc = _start(env, port)
        deadline = time.monotonic() + 60
        while _files(imagery_dir) or list(tmp.glob("fieldrx-upload-*")):
            assert time.monotonic() < deadline, (_files(imagery_dir), list(tmp.iterdir()))
            time.sleep(0.2)
    finally:
        proc.stop()
