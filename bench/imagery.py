"""Imagery figures: tile latency, large-GeoTIFF ingest, per-cell NDVI.

Run: .venv/bin/python bench/imagery.py [--ingest-mb 1024] [--tiles 300] [--cells 100000]
     [--only tiles|cells|ingest ...]

1. Tiles: a 10,000 x 10,000 px RGB orthophoto (0.1 m, 1 km x 1 km, UTM 49N) is converted to
   a COG, then ``imagery.tiles.render_tile`` (what GET /tiles/imagery/... runs after its
   one-row lookup) renders random 256 px web-mercator tiles inside the image at zooms
   16..21: p50/p99 cold (first request of each tile) and warm (the same tiles again).
2. Ingest: an uncompressed RGB GeoTIFF of ``--ingest-mb`` MB (default 1024: the issue's
   1 GB; written window by window, never whole in memory) goes through ``ingest`` (the
   spawned, time-limited converter the upload endpoint uses), called from a fresh Python
   process that stands in for the API worker. Figures: wall time and peak RSS (VmHWM) of
   the calling process and of the converter; the larger is the ingest's peak. Goal:
   peak RSS < 1 GB. Needs about 2x ``--ingest-mb`` of free disk in the temp dir.
3. Per-cell NDVI: ``--cells`` 2.3 m x 5 m cells (seed 001's implement width and cell
   length), rotated 20 degrees, over a 0.25 m NDVI raster; time of ``cell_ndvi``.

Ends with one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "backend"))

UTM = 32649
X0, Y0 = 200_000.0, 3_560_000.0


def _write_rgb(path: Path, size_px: int, res: float, compress: str | None) -> None:
    """Windowed write (never the whole raster in memory): a smooth pattern with noise."""
    import rasterio
    from rasterio.transform import from_origin
    from rasterio.windows import Window

    meta = {
        "driver": "GTiff",
        "width": size_px,
        "height": size_px,
        "count": 3,
        "dtype": "uint8",
        "crs": f"EPSG:{UTM}",
        "transform": from_origin(X0, Y0 + size_px * res, res, res),
        "tiled": True,
        "blockxsize": 512,
        "blockysize": 512,
        "BIGTIFF": "IF_SAFER",
    }
    if compress:
        meta["compress"] = compress
    rng = np.random.default_rng(0)
    rows = 512
    xs = np.arange(size_px, dtype=np.float32)
    with rasterio.open(path, "w", **meta) as dst:
        for r0 in range(0, size_px, rows):
            h = min(rows, size_px - r0)
            yy = np.arange(r0, r0 + h, dtype=np.float32)[:, None]
            base = 120 + 60 * np.sin(xs[None, :] / 700.0) * np.cos(yy / 900.0)
            noise = rng.integers(0, 24, size=(h, size_px), dtype=np.uint8)
            for b in range(3):
                band = (base * (0.8 + 0.15 * b)).astype(np.uint8) + noise
                dst.write(band, b + 1, window=Window(0, r0, size_px, h))


def _spec(size_m: float, kind: str) -> object:
    from fieldrx.imagery.ingest import IngestSpec
    from pyproj import Transformer
    from shapely import wkb
    from shapely.geometry import MultiPolygon, box
    from shapely.ops import transform

    tr = Transformer.from_crs(UTM, 4326, always_xy=True)
    field = transform(tr.transform, box(X0 + 10, Y0 + 10, X0 + size_m - 10, Y0 + size_m - 10))
    return IngestSpec(kind=kind, field_wkb=wkb.dumps(MultiPolygon([field])), utm_epsg=UTM)


def bench_tiles(tmp: Path, n_tiles: int) -> dict:
    import morecantile
    from fieldrx.imagery.ingest import inspect_and_convert
    from fieldrx.imagery.tiles import render_tile
    from pyproj import Transformer

    size, res = 10_000, 0.1
    src, cog = tmp / "ortho10k.tif", tmp / "ortho10k.cog.tif"
    t0 = time.perf_counter()
    _write_rgb(src, size, res, "deflate")
    t1 = time.perf_counter()
    inspect_and_convert(src, cog, _spec(size * res, "orthophoto"))
    t2 = time.perf_counter()
    src.unlink()
    tms = morecantile.tms.get("WebMercatorQuad")
    tr = Transformer.from_crs(UTM, 4326, always_xy=True)
    rnd = random.Random(1)
    tiles = []
    for _ in range(n_tiles):
        z = rnd.choice([16, 17, 18, 19, 20, 21])
        lon, lat = tr.transform(X0 + rnd.uniform(50, 950), Y0 + rnd.uniform(50, 950))
        tiles.append(tms.tile(lon, lat, z))
    bands = {"r": 1, "g": 2, "b": 3}

    def run() -> list[float]:
        out = []
        for t in tiles:
            a = time.perf_counter()
            png = render_tile(cog, "orthophoto", bands, t.z, t.x, t.y)
            out.append((time.perf_counter() - a) * 1000)
            assert png is not None and png[:4] == b"\x89PNG"
        return out

    cold = run()
    warm = run()
    by_zoom = {
        z: round(float(np.median([w for w, t in zip(warm, tiles, strict=True) if t.z == z])), 1)
        for z in sorted({t.z for t in tiles})
    }
    print(
        f"tiles: 10,000 x 10,000 px RGB (write {t1 - t0:.1f} s, COG {t2 - t1:.1f} s, "
        f"{cog.stat().st_size / 1e6:.0f} MB); {n_tiles} random tiles z16-21"
    )
    print(f"  cold p50 {np.percentile(cold, 50):.1f} ms  p99 {np.percentile(cold, 99):.1f} ms")
    print(f"  warm p50 {np.percentile(warm, 50):.1f} ms  p99 {np.percentile(warm, 99):.1f} ms")
    print(f"  warm p50 by zoom (ms): {by_zoom}")
    cog.unlink()
    return {
        "tile_cold_p50_ms": round(float(np.percentile(cold, 50)), 2),
        "tile_cold_p99_ms": round(float(np.percentile(cold, 99)), 2),
        "tile_warm_p50_ms": round(float(np.percentile(warm, 50)), 2),
        "tile_warm_p99_ms": round(float(np.percentile(warm, 99)), 2),
    }


def ingest_child(src: str, dst: str, size_m: float) -> None:
    """Run in a fresh process: ``ingest`` as the upload endpoint calls it; print the result
    and the peak RSS of this process and of its converter as one JSON line.

    Peak RSS is VmHWM (``imagery.ingest.peak_rss_mb``), not ``ru_maxrss``: a process
    started by fork + exec inherits in ``ru_maxrss`` the RSS its parent had at the fork
    (here the bench, which just wrote the 1 GB file through GDAL's block cache: 1.2 GB).
    ``ru_maxrss`` of the waited-for children is printed as a cross-check of the converter.
    """
    import resource

    from fieldrx.imagery.ingest import ingest, peak_rss_mb

    t0 = time.perf_counter()
    result = ingest(Path(src), Path(dst), _spec(size_m, "orthophoto"), timeout_s=3600)
    wall = time.perf_counter() - t0
    kb_children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # KiB on Linux
    print(
        json.dumps(
            {
                "wall_s": wall,
                "size_bytes": result.size_bytes,
                "converter_vmhwm_mb": result.peak_rss_mb,
                "caller_vmhwm_mb": peak_rss_mb(),
                "children_maxrss_mb": kb_children / 1024.0,
            }
        )
    )


def bench_ingest(tmp: Path, mb: int) -> dict:
    import subprocess

    size = int(math.sqrt(mb * 1024 * 1024 / 3))
    res = 0.05
    src, cog = tmp / "big.tif", tmp / "big.cog.tif"
    t0 = time.perf_counter()
    _write_rgb(src, size, res, None)
    t1 = time.perf_counter()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    out = subprocess.run(
        [sys.executable, __file__, "--ingest-child", str(src), str(cog), str(size * res)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    t2 = time.perf_counter()
    fig = json.loads(out.stdout.strip().splitlines()[-1])
    src_bytes = src.stat().st_size
    src.unlink()
    cog.unlink()
    peak = max(fig["caller_vmhwm_mb"] or 0, fig["converter_vmhwm_mb"] or 0)
    print(
        f"ingest: {size} x {size} x 3 uint8 uncompressed GeoTIFF, {src_bytes / 1e6:,.0f} MB "
        f"({src_bytes / 1024**3:.2f} GiB, written in {t1 - t0:.1f} s) -> COG "
        f"{fig['size_bytes'] / 1e6:.0f} MB in {fig['wall_s']:.1f} s "
        f"({t2 - t1:.1f} s with the caller's start-up)"
    )
    print(
        f"  peak RSS {peak:.0f} MB (goal < 1024 MB): converter {fig['converter_vmhwm_mb']:.0f} MB "
        f"(VmHWM), calling process {fig['caller_vmhwm_mb']:.0f} MB (VmHWM); "
        f"converter ru_maxrss {fig['children_maxrss_mb']:.0f} MB"
    )
    return {
        "ingest_source_mb": round(src_bytes / 1e6),
        "ingest_s": round(fig["wall_s"], 1),
        "ingest_peak_rss_mb": round(peak),
        "ingest_converter_rss_mb": round(fig["converter_vmhwm_mb"] or 0),
    }


def bench_cells(tmp: Path, n_cells: int) -> dict:
    import rasterio
    import shapely
    from fieldrx.imagery.stats import cell_ndvi
    from rasterio.transform import from_origin
    from shapely import affinity

    swaths = int(math.sqrt(n_cells * 5.0 / 2.3))
    per = math.ceil(n_cells / swaths)
    width_m, height_m = swaths * 2.3, per * 5.0
    i, j = np.divmod(np.arange(n_cells), per)
    x0 = X0 + 50 + i * 2.3
    y0 = Y0 + 50 + j * 5.0
    cells = shapely.box(x0, y0, x0 + 2.3, y0 + 5.0)
    centre = ((X0 + 50 + width_m / 2), (Y0 + 50 + height_m / 2))
    cells = np.array([affinity.rotate(c, 20, origin=centre) for c in cells], dtype=object)
    ext = max(width_m, height_m) * 1.5 + 100
    res = 0.25
    npx = int(ext / res)
    path = tmp / "ndvi.tif"
    meta = {
        "driver": "GTiff",
        "width": npx,
        "height": npx,
        "count": 1,
        "dtype": "float32",
        "crs": f"EPSG:{UTM}",
        "tiled": True,
        "compress": "deflate",
        "transform": from_origin(centre[0] - ext / 2, centre[1] + ext / 2, res, res),
    }
    from rasterio.windows import Window

    xs = np.arange(npx, dtype=np.float32)
    with rasterio.open(path, "w", **meta) as dst:
        for r0 in range(0, npx, 1024):
            h = min(1024, npx - r0)
            yy = np.arange(r0, r0 + h, dtype=np.float32)[:, None]
            dst.write(
                (0.5 + 0.3 * np.sin(xs[None, :] / 300.0) * np.cos(yy / 400.0)).astype("float32"),
                1,
                window=Window(0, r0, npx, h),
            )
    t0 = time.perf_counter()
    stats = cell_ndvi(path, "ndvi", {"ndvi": 1}, cells, UTM)
    dt = time.perf_counter() - t0
    path.unlink()
    print(
        f"per-cell NDVI: {n_cells:,} cells of 2.3 x 5 m over a {npx} x {npx} px 0.25 m NDVI "
        f"raster: {dt:.2f} s ({stats.info['samples']:,} samples at "
        f"{stats.info['sample_step']:.2f} m; {stats.info['cells_without_data']} cells without data)"
    )
    return {"cells": n_cells, "cell_ndvi_s": round(dt, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ingest-mb", type=int, default=1024)
    ap.add_argument("--tiles", type=int, default=300)
    ap.add_argument("--cells", type=int, default=100_000)
    ap.add_argument("--only", choices=["tiles", "cells", "ingest"], action="append")
    ap.add_argument(
        "--ingest-child", nargs=3, metavar=("SRC", "DST", "SIZE_M"), help=argparse.SUPPRESS
    )
    args = ap.parse_args()
    if args.ingest_child:
        src, dst, size_m = args.ingest_child
        ingest_child(src, dst, float(size_m))
        return
    only = set(args.only or ["tiles", "cells", "ingest"])
    out: dict = {"bench": "imagery"}
    with tempfile.TemporaryDirectory(prefix="fieldrx-imagery-bench-") as d:
        tmp = Path(d)
        if "tiles" in only:
            out.update(bench_tiles(tmp, args.tiles))
        if "cells" in only:
            out.update(bench_cells(tmp, args.cells))
        if "ingest" in only:
            out.update(bench_ingest(tmp, args.ingest_mb))
    out["cpus"] = os.cpu_count()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
