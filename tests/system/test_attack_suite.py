"""The attack suite: hostile requests fired together at a real API process while a reader
lists fields. Each hostile request must be refused or bounded by its limit, the reader's
95th-percentile answer stay under 1 s, and the API process stay under 1.5 GB resident.

Fired at once (one attacker organisation; the reader is another):
- an ISOXML import confirm with 1 mm cells (the cost estimate refuses it),
- a 10,000-task plan batch (the organisation's task quota refuses it),
- three imagery DEFLATE bombs of float32 zeros (the conversion budget refuses them),
- four archives of 2 x 250 MiB that inflate in the bounded workers, never in the API.
"""

from __future__ import annotations

import io
import threading
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
import rasterio
import shapely
from sqlalchemy import text

from tests.fleet.procs import BIN, Proc, free_port
from tests.imagery.rasters import UTM, X0, Y0, field_geojson
from tests.support import feature
from tests.support.plans import rectangle

API = "/api/v1"
pytestmark = pytest.mark.slow
READER_P95_S = 1.0
RSS_LIMIT_MB = 1536
N_BATCH = 10_000


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def _small_taskdata() -> bytes:
    from fieldrx.agronomy.cells import CellTable
    from fieldrx.formats.isoxml import write_isoxml_grid

    c = CellTable.rectangle(32649, 624000.0, 3556000.0, 2, 2, 20.0, 20.0).with_rates(
        np.array([100.0, 200.0, 300.0, 400.0])
    )
    return write_isoxml_grid(c, "g", shapely.union_all(c.polygons_wgs84()), grid_cell_m=10.0)


def _archive() -> bytes:
    """Two members of 250 MiB each (zeros: a few hundred KB compressed)."""
    out = io.BytesIO()
    block = b"\0" * (1 << 20)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("TASKDATA.XML", "GRD00001.BIN"):
            with z.open(name, "w", force_zip64=True) as f:
                for _ in range(250):
                    f.write(block)
    return out.getvalue()


def _deflate_bomb(path: Path) -> bytes:
    """12,000 x 12,000 float32 zeros (549 MiB declared) in well under 1 MiB of DEFLATE."""
    w = h = 12_000
    meta = {
        "driver": "GTiff",
        "width": w,
        "height": h,
        "count": 1,
        "dtype": "float32",
        "tiled": True,
        "blockxsize": 512,
        "blockysize": 512,
        "compress": "deflate",
        "crs": rasterio.crs.CRS.from_user_input(UTM),
        "transform": rasterio.transform.from_bounds(X0, Y0, X0 + 1200, Y0 + 1200, w, h),
    }
    zeros = np.zeros((512, w), "float32")
    with rasterio.open(path, "w", **meta) as dst:
        for row in range(0, h, 512):
            n = min(512, h - row)
            dst.write(zeros[:n], 1, window=rasterio.windows.Window(0, row, w, n))
    return path.read_bytes()


@pytest.fixture()
def api(database_url: str, tmp_path: Path) -> Iterator[tuple[str, Proc]]:
    port = free_port()
    env = {"DATABASE_URL": database_url, "FIELDRX_IMAGERY_DIR": str(tmp_path / "imagery")}
    proc = Proc([str(BIN / "fieldrx"), "serve", "--port", str(port), "--quiet"], env)
    try:
        deadline = time.monotonic() + 120
        url = f"http://127.0.0.1:{port}"
        while True:
            try:
                if httpx.get(f"{url}{API}/health", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            assert time.monotonic() < deadline, proc.lines[-20:]
            time.sleep(0.2)
        yield url, proc
    finally:
        proc.stop()


def test_attack_suite(api, make_org, db, tmp_path) -> None:  # noqa: ANN001
    url, proc = api
    victim, attacker = make_org(), make_org()
    ah = attacker.headers()
    with httpx.Client(base_url=url, timeout=60) as c:
        for i in range(20):
            r = c.post(
                f"{API}/fields",
                headers=victim.headers(),
                json=feature(rectangle(112.3 + i * 0.01, 32.1, 200, 150), name=f"v{i}"),
            )
            assert r.status_code == 201, r.text
        img_field = c.post(f"{API}/fields", headers=ah, json=feature(field_geojson())).json()["id"]
        small = _small_taskdata()
        pre = c.post(f"{API}/imports/isoxml", headers=ah, files={"files": ("T.zip", small)})
        assert pre.status_code == 200, pre.text
    sha = pre.json()["sha256"]
    db.execute(
        text(
            "INSERT INTO fields (organisation_id, name, crop, notes, boundary, utm_epsg, area_m2)"
            " SELECT :o, 'f' || g, '', '', ST_Multi(ST_MakeEnvelope(112.3 + g * 1e-4, 32.1,"
            " 112.3 + g * 1e-4 + 5e-5, 32.10005, 4326)), 32649, 25.0"
            " FROM generate_series(1, :n) g"
        ),
        {"o": attacker.id, "n": N_BATCH},
    )
    db.commit()
    batch_ids = list(
        db.scalars(
            text("SELECT id FROM fields WHERE organisation_id = :o AND name LIKE 'f%'"),
            {"o": attacker.id},
        )
    )
    assert len(batch_ids) == N_BATCH
    archive = _archive()
    bomb = _deflate_bomb(tmp_path / "bomb.tif")

    hostile = [
        (
            "tiny-cell import confirm",
            f"{API}/imports/isoxml?confirm={sha}&swath_width_m=0.002&cell_length_m=0.001",
            {"files": {"files": ("T.zip", small)}},
        ),
        (
            "10,000-task batch",
            f"{API}/plans/batch",
            {"json": {"field_ids": batch_ids, "params": {"swath_width_m": 4, "cell_length_m": 5}}},
        ),
        *[
            (
                f"imagery bomb {i}",
                f"{API}/fields/{img_field}/imagery",
                {"files": {"file": ("b.tif", bomb)}, "data": {"kind": "ndvi"}},
            )
            for i in range(3)
        ],
        *[
            (f"archive {i}", f"{API}/imports/isoxml", {"files": {"files": ("A.zip", archive)}})
            for i in range(4)
        ],
    ]
    results: dict[str, tuple[int, float, str]] = {}
    stop = threading.Event()
    reads: list[float] = []
    rss: list[float] = []

    def attack(name: str, path: str, kw: dict) -> None:
        t0 = time.monotonic()
        try:
            r = httpx.post(url + path, headers=ah, timeout=300, **kw)
            results[name] = (r.status_code, time.monotonic() - t0, r.text[:200])
        except httpx.HTTPError as exc:
            results[name] = (0, time.monotonic() - t0, repr(exc))

    def read() -> None:
        with httpx.Client(base_url=url, headers=victim.headers(), timeout=30) as c:
            c.get(f"{API}/fields")
            while not stop.is_set():
                t0 = time.perf_counter()
                r = c.get(f"{API}/fields")
                reads.append(time.perf_counter() - t0)
                assert r.status_code == 200
                rss.append(_rss_mb(proc.p.pid))
                time.sleep(0.05)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    threads = [threading.Thread(target=attack, args=h) for h in hostile]
    t_start = time.monotonic()
    for t in threads:
        t.start()
    for t in threads:
        t.join(330)
    took = time.monotonic() - t_start
    stop.set()
    reader.join(30)

    reads.sort()
    p95 = reads[int(0.95 * (len(reads) - 1))]
    print(
        f"\nattack suite: {took:.1f} s; reader n={len(reads)} median="
        f"{reads[len(reads) // 2] * 1e3:.0f} ms p95={p95 * 1e3:.0f} ms max={reads[-1] * 1e3:.0f}"
        f" ms; API RSS max {max(rss):.0f} MB"
    )
    for name, (code, secs, body) in sorted(results.items()):
        print(f"  {name}: {code} in {secs:.1f} s: {body[:120]}")
    assert set(results) == {h[0] for h in hostile}
    for name, (code, _, body) in results.items():
        assert code in (413, 422, 429, 503), (name, code, body)
    assert results["tiny-cell import confirm"][0] == 422
    assert "cell_length_m must be >= 0.5" in results["tiny-cell import confirm"][2]
    assert results["10,000-task batch"][0] in (422, 429)
    assert "quota" in results["10,000-task batch"][2]
    for i in range(3):
        code, _, body = results[f"imagery bomb {i}"]
        assert (code == 422 and "times its file size" in body) or code == 503, body
    assert (
        db.scalar(text("SELECT count(*) FROM tasks WHERE organisation_id = :o"), {"o": attacker.id})
        == 0
    )
    assert p95 < READER_P95_S, p95
    assert max(rss) < RSS_LIMIT_MB, max(rss)
