"""Validate an uploaded GeoTIFF and convert it to a Cloud-Optimized GeoTIFF (COG).

Everything raster-specific is GDAL's (through rasterio): opening, georeferencing,
reprojection of the footprint and the COG writer, which works block by block, so a raster
far larger than memory is converted with memory bounded by ``GDAL_CACHEMAX`` plus one
block per band. What this module adds is the product's rules: which kinds exist and which
bands they need, what is too big, that the raster must overlap the field, and that a
rejected upload leaves nothing behind.

The conversion runs in a separate process (``ingest``) so that the API's event loop is
never blocked, and so that a raster that takes too long (a decompression bomb: a few MB
of DEFLATE that expand to billions of pixels) can be stopped: a GDAL call in a thread
cannot be interrupted, a process can.
"""

from __future__ import annotations

import datetime as dt
import math
import multiprocessing as mp
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from fieldrx.errors import Cancelled
from fieldrx.imagery import KINDS, ImageryError
from fieldrx.proctag import process_tag

# First bytes of a classic TIFF and a BigTIFF, little and big endian (TIFF 6.0 sec. 2,
# BigTIFF spec). Anything else is not a TIFF, whatever its name says.
TIFF_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
MAX_BLOCK_BYTES = 256 * 1024**2  # one strip/tile GDAL must hold in memory to decode
GDAL_ENV = {
    "GDAL_CACHEMAX": 256,  # MB: the conversion's block cache, the bulk of its memory
    "GDAL_DISABLE_READDIR_ON_OPEN": "EMPTY_DIR",  # no sidecar scan of the upload folder
    "GDAL_NUM_THREADS": "1",
}
COG_OPTIONS = {
    "COMPRESS": "DEFLATE",
    "PREDICTOR": "YES",
    "BLOCKSIZE": 512,
    "OVERVIEW_RESAMPLING": "AVERAGE",
    "BIGTIFF": "IF_SAFER",
    "NUM_THREADS": "1",
}
# Orthophotos are for display only: stored in web mercator on the web-map tile grid
# (GDAL's GoogleMapsCompatible tiling scheme), so a map tile is one aligned block read with
# no warping (bench/imagery.py: ~6x faster tiles). NDVI and multispectral images keep their
# own grid: per-cell statistics read the original pixels, not resampled ones.
COG_KIND_OPTIONS: dict[str, dict[str, Any]] = {
    "orthophoto": {
        "TILING_SCHEME": "GoogleMapsCompatible",
        "BLOCKSIZE": 256,
        "RESAMPLING": "BILINEAR",
    },
}


@dataclass
class IngestSpec:
    """What the caller knows: kind, band roles (1-based) and the field it belongs to."""

    kind: str
    field_wkb: bytes
    utm_epsg: int
    red_band: int | None = None
    nir_band: int | None = None
    max_pixels: int = 2_000_000_000
    acquired_on: str | None = None
    # conversion budget: declared uncompressed bytes per byte of file (see _check_budget)
    max_expansion: float = 400.0


@dataclass
class IngestResult:
    """What is recorded about the stored COG."""

    source_crs: str
    width: int
    height: int
    band_count: int
    dtype: str
    bands: dict[str, int]
    nodata: float | None
    resolution_m: float
    footprint_wkb: bytes
    overlap_share: float
    acquired_on: str | None
    size_bytes: int
    warnings: list[str] = field(default_factory=list)
    peak_rss_mb: float | None = None


def peak_rss_mb() -> float | None:
    """This process's peak resident memory (VmHWM, Linux). Not ru_maxrss: that includes
    the parent's memory the child had between fork and exec."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def check_magic(path: Path) -> None:
    with open(path, "rb") as fh:
        head = fh.read(4)
    if head not in TIFF_MAGIC:
        raise ImageryError(
            f"the file is not a TIFF (it starts with {head!r}, a GeoTIFF starts with "
            "'II*' or 'MM'); upload a GeoTIFF"
        )


def _band_roles(src: Any, spec: IngestSpec) -> dict[str, int]:
    """Band roles per kind; a mismatch is a 422 naming what the file has."""
    n = src.count
    if spec.kind == "orthophoto":
        if n < 3:
            raise ImageryError(
                f"an orthophoto needs 3 (RGB) or 4 (RGBA) bands, the file has {n}; "
                "upload single-band NDVI as kind 'ndvi'"
            )
        return {"r": 1, "g": 2, "b": 3}
    if spec.kind == "ndvi":
        if n != 1:
            raise ImageryError(
                f"an NDVI raster has exactly 1 band, the file has {n}; upload red/NIR "
                "bands as kind 'multispectral' with red_band and nir_band"
            )
        if not src.dtypes[0].startswith("float"):
            raise ImageryError(
                f"an NDVI raster must hold NDVI as floating point (-1..1), the band is "
                f"{src.dtypes[0]}"
            )
        return {"ndvi": 1}
    red, nir = spec.red_band, spec.nir_band
    descriptions = [str(d or "").strip().lower() for d in src.descriptions]
    if red is None and "red" in descriptions:
        red = descriptions.index("red") + 1
    if nir is None and "nir" in descriptions:
        nir = descriptions.index("nir") + 1
    if red is None or nir is None:
        raise ImageryError(
            "a multispectral raster needs red_band and nir_band (1-based band numbers); "
            f"the file has {n} bands described as {descriptions}"
        )
    for name, b in (("red_band", red), ("nir_band", nir)):
        if not 1 <= b <= n:
            raise ImageryError(f"{name} {b} does not exist: the file has bands 1..{n}")
    if red == nir:
        raise ImageryError(f"red_band and nir_band are both band {red}")
    return {"red": int(red), "nir": int(nir)}


def _check_size(src: Any, spec: IngestSpec) -> None:
    import numpy as np

    pixels = src.width * src.height
    item = max(np.dtype(d).itemsize for d in src.dtypes)
    declared = pixels * src.count * item
    if pixels > spec.max_pixels:
        raise ImageryError(
            f"the raster claims {src.width} x {src.height} pixels x {src.count} bands "
            f"({declared / 1024**3:.1f} GB uncompressed), more than the limit of "
            f"{spec.max_pixels:,} pixels"
        )
    for i, (bh, bw) in enumerate(src.block_shapes, start=1):
        block = (
            bh
            * bw
            * item
            * (src.count if src.interleaving and src.interleaving.name == "PIXEL" else 1)
        )
        if block > MAX_BLOCK_BYTES:
            raise ImageryError(
                f"band {i} is stored in blocks of {bw} x {bh} pixels "
                f"({block / 1024**2:.0f} MB each, limit {MAX_BLOCK_BYTES // 1024**2} MB); "
                "save it tiled (gdal_translate -co TILED=YES)"
            )


def _check_budget(src: Any, spec: IngestSpec, file_bytes: int) -> None:
    """The conversion budget: refuse, before decoding a pixel, a raster whose declared
    size is more than ``max_expansion`` times its file. DEFLATE's longest match is 258
    bytes (RFC 1951 sec. 3.2.5), so it compresses at most about 1032:1, and a few MB that
    decode to gigabytes are all-but-empty data (a decompression bomb, or missing tiles);
    real orthophotos and index maps compress a few to about a hundred times."""
    import numpy as np

    item = max(np.dtype(d).itemsize for d in src.dtypes)
    declared = src.width * src.height * src.count * item
    ratio = declared / max(file_bytes, 1)
    if ratio > spec.max_expansion:
        raise ImageryError(
            f"the raster declares {src.width} x {src.height} pixels x {src.count} bands "
            f"({declared / 1024**2:,.0f} MB uncompressed) in a {file_bytes / 1024**2:,.1f} MB "
            f"file, {ratio:,.0f} times its file size (limit {spec.max_expansion:g}, "
            "FIELDRX_IMAGERY_MAX_EXPANSION): a decompression bomb or a mostly empty raster; "
            "crop it to the field"
        )


def _footprint(src: Any) -> Any:
    """The raster's outline (its four corners, edges densified) in WGS84."""
    import shapely
    from rasterio.warp import transform_geom
    from shapely.geometry import MultiPolygon, Polygon, mapping, shape

    t = src.transform
    corners = [t @ (0, 0), t @ (src.width, 0), t @ (src.width, src.height), t @ (0, src.height)]
    ring = shapely.segmentize(Polygon(corners), max_segment_length=_edge(corners) / 32.0)
    geom = shape(transform_geom(src.crs, "EPSG:4326", mapping(ring)))
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    if isinstance(geom, Polygon):
        geom = MultiPolygon([geom])
    return geom


def _edge(corners: list[tuple[float, float]]) -> float:
    (x0, y0), (x1, y1), (_, _), (x3, y3) = corners
    return max(math.hypot(x1 - x0, y1 - y0), math.hypot(x3 - x0, y3 - y0), 1e-9)


def _resolution_m(src: Any, utm_epsg: int) -> float:
    """Ground size of the centre pixel (sqrt of its area) in the field's UTM zone."""
    from pyproj import Transformer

    t = src.transform
    cx, cy = src.width / 2.0, src.height / 2.0
    pts = [t @ (cx, cy), t @ (cx + 1, cy), t @ (cx, cy + 1)]
    tr = Transformer.from_crs(src.crs, f"EPSG:{utm_epsg}", always_xy=True)
    (x0, y0), (x1, y1), (x2, y2) = (tr.transform(x, y) for x, y in pts)
    area = abs((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))
    return math.sqrt(area)


def _acquired_on(src: Any, given: str | None) -> str | None:
    if given:
        return dt.date.fromisoformat(given).isoformat()
    stamp = src.tags().get("TIFFTAG_DATETIME", "")
    try:
        return dt.datetime.strptime(stamp.strip(), "%Y:%m:%d %H:%M:%S").date().isoformat()
    except ValueError:
        return None


def inspect_and_convert(src_path: Path, dst_path: Path, spec: IngestSpec) -> IngestResult:
    """Validate ``src_path`` and write the COG to ``dst_path``.

    GDAL's COG writer keeps temporary files (overviews) beside its output, so the COG is
    written inside a private work directory next to ``dst_path`` and moved into place only
    when complete. Raises ImageryError for anything the user must fix; on any error (and on
    success) the work directory is removed, so nothing but the finished COG remains.
    """
    import rasterio
    import rasterio.shutil
    from rasterio.errors import RasterioError
    from shapely import wkb
    from shapely.geometry import MultiPolygon

    from fieldrx.geo.crs import to_utm

    if spec.kind not in KINDS:
        raise ImageryError(f"kind must be one of {list(KINDS)}, got {spec.kind!r}")
    check_magic(src_path)
    work = work_dir(dst_path)
    work.mkdir(parents=True, exist_ok=True)
    part = work / "cog.tif"
    try:
        with rasterio.Env(**GDAL_ENV):
            try:
                src = rasterio.open(src_path, driver="GTiff")
            except RasterioError as exc:
                raise ImageryError(f"the TIFF cannot be read as a raster: {exc}") from exc
            with src:
                if src.transform.is_identity and src.gcps[0]:
                    raise ImageryError(
                        "the TIFF is georeferenced by ground control points only; warp it "
                        "first (gdalwarp) so that it has a geotransform"
                    )
                if src.crs is None or src.transform.is_identity:
                    raise ImageryError(
                        "the TIFF is not georeferenced (no coordinate reference system or "
                        "geotransform); export it as a GeoTIFF from the photogrammetry software"
                    )
                _check_size(src, spec)
                _check_budget(src, spec, src_path.stat().st_size)
                bands = _band_roles(src, spec)
                foot = _footprint(src)
                boundary = wkb.loads(spec.field_wkb)
                inter = foot.intersection(boundary)
                if inter.is_empty or inter.area <= 0:
                    raise ImageryError(
                        "the raster does not overlap the field (raster bounds lon/lat "
                        f"{[round(v, 6) for v in foot.bounds]}, field bounds "
                        f"{[round(v, 6) for v in boundary.bounds]}); check its CRS "
                        f"({src.crs.to_string()})"
                    )
                share = to_utm(inter, spec.utm_epsg).area / max(
                    to_utm(boundary, spec.utm_epsg).area, 1e-9
                )
                result = IngestResult(
                    source_crs=src.crs.to_string(),
                    width=src.width,
                    height=src.height,
                    band_count=src.count,
                    dtype=src.dtypes[0],
                    bands=bands,
                    nodata=None if src.nodata is None else float(src.nodata),
                    resolution_m=_resolution_m(src, spec.utm_epsg),
                    footprint_wkb=wkb.dumps(
                        foot if isinstance(foot, MultiPolygon) else MultiPolygon([foot])
                    ),
                    overlap_share=min(1.0, share),
                    acquired_on=_acquired_on(src, spec.acquired_on),
                    size_bytes=0,
                )
                if share < 0.5:
                    result.warnings.append(f"the raster covers only {share:.0%} of the field")
                try:
                    options = {**COG_OPTIONS, **COG_KIND_OPTIONS.get(spec.kind, {})}
                    rasterio.shutil.copy(src, part, driver="COG", **options)
                except OSError:
                    raise  # our disk, not the user's file
                except Exception as exc:  # GDAL's CPLE_* errors: corrupt or truncated data
                    raise ImageryError(f"the raster cannot be decoded: {exc}") from exc
        os.replace(part, dst_path)
        result.size_bytes = dst_path.stat().st_size
        result.peak_rss_mb = peak_rss_mb()
        return result
    finally:
        shutil.rmtree(work, ignore_errors=True)


def work_dir(dst_path: Path) -> Path:
    """Where the conversion of ``dst_path`` keeps its partial output."""
    return dst_path.with_name(f".work-{dst_path.name}")


def without_paths(message: str, src: str, dst: str) -> str:
    """GDAL names the files it read or wrote: the server's paths never reach the user."""
    for path, name in (
        (str(work_dir(Path(dst))), "the output"),
        (dst, "the output"),
        (src, "the upload"),
        (str(Path(src).parent), "the upload folder"),
        (str(Path(dst).parent), "the image folder"),
        (Path(src).name, "the upload"),
        (Path(dst).name, "the output"),
    ):
        message = message.replace(path, name)
    return message


def _child(conn: Any, src: str, dst: str, spec: IngestSpec, caller_tag: str) -> None:
    from fieldrx.services.bounded import watch_caller

    watch_caller(caller_tag)  # a converter never outlives the server or worker that started it
    try:
        res = inspect_and_convert(Path(src), Path(dst), spec)
        conn.send(("ok", asdict(res)))
    except ImageryError as exc:
        conn.send(("error", without_paths(str(exc), src, dst)))
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises
        conn.send(("crash", without_paths(f"{type(exc).__name__}: {exc}", src, dst)))
    finally:
        conn.close()


def ingest(
    src: Path,
    dst: Path,
    spec: IngestSpec,
    timeout_s: float,
    should_stop: Callable[[], bool] | None = None,
    slot_wait_s: float | None = None,
) -> IngestResult:
    """``inspect_and_convert`` in a fresh process, stopped after ``timeout_s``.

    The conversion takes one of the process's heavy-work slots (``services.bounded``, the
    same as planning and imports), waiting up to ``slot_wait_s`` (default ``timeout_s``)
    for one, else ``Busy`` (503). On timeout the child is killed and its partial output
    removed (it writes to a work directory and renames only on success, so ``dst`` never
    holds a partial COG). A background task passes ``should_stop`` (polled every second):
    when it turns true the child is killed the same way and ``Cancelled`` is raised.
    """
    from fieldrx.services.bounded import heavy_slot

    wait = timeout_s if slot_wait_s is None else slot_wait_s
    with heavy_slot(wait, "the imagery conversion"):
        return _convert(src, dst, spec, timeout_s, should_stop)


def _convert(
    src: Path,
    dst: Path,
    spec: IngestSpec,
    timeout_s: float,
    should_stop: Callable[[], bool] | None,
) -> IngestResult:
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    tag = process_tag()
    proc = ctx.Process(target=_child, args=(child, str(src), str(dst), spec, tag), daemon=True)
    proc.start()
    child.close()
    deadline = time.monotonic() + timeout_s
    try:
        while not parent.poll(max(0.0, min(1.0, deadline - time.monotonic()))):
            if should_stop is not None and should_stop():
                proc.kill()
                proc.join(5)
                dst.unlink(missing_ok=True)
                raise Cancelled("the imagery conversion was cancelled; nothing was stored")
            if time.monotonic() < deadline:
                continue
            raise ImageryError(
                f"converting the raster took longer than {timeout_s:g} s and was stopped "
                "(a raster that expands to far more pixels than its file size suggests is "
                "refused this way); upload a tiled, compressed GeoTIFF"
            )
        try:
            status, payload = parent.recv()
        except EOFError as exc:
            proc.join(5)
            raise ImageryError(
                f"the raster could not be processed (the converter exited with code "
                f"{proc.exitcode})"
            ) from exc
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5)
        parent.close()
        shutil.rmtree(work_dir(dst), ignore_errors=True)  # a killed child cannot clean up
    if status == "ok":
        return IngestResult(**payload)
    if status == "error":
        raise ImageryError(payload)
    dst.unlink(missing_ok=True)
    raise RuntimeError(f"imagery conversion failed: {payload}")
