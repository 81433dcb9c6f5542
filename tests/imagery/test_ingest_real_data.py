"""Real imagery shipped in registry packages (tests/imagery/realdata.py), uploaded as it is:
a Landsat 7 ETM+ scene in NC State Plane (red band 3, NIR band 4) as ``multispectral`` ->
per-cell NDVI on a field inside its footprint -> NDVI zones; a real RGB image in EPSG:4326
as ``orthophoto`` -> tiles that show its pixels."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import rasterio
import shapely
from PIL import Image
from pyproj import Transformer
from rasterio.windows import from_bounds as window_from_bounds
from shapely.geometry import shape

from tests.imagery.realdata import LANDSAT_NC, RGB_RMNP, member
from tests.support import feature
from tests.support.prescriptions import all_cells

API = "/api/v1"


def _field(client, org, src_crs: object, x0: float, y0: float, w: float, h: float) -> int:  # noqa: ANN001
    """A w x h field (in the raster's CRS units) with its south-west corner at (x0, y0)."""
    tr = Transformer.from_crs(src_crs, 4326, always_xy=True)
    ring = [
        list(tr.transform(x, y))
        for x, y in ((x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h))
    ]
    geom = {"type": "Polygon", "coordinates": [ring + [ring[0]]]}
    r = client.post(f"{API}/fields", headers=org.headers(), json=feature(geom, name="real"))
    assert r.status_code == 201, r.text
    return r.json()["id"]


def _upload(client, org, field_id: int, path: Path, kind: str, **form: object) -> dict:  # noqa: ANN001
    with open(path, "rb") as fh:
        r = client.post(
            f"{API}/fields/{field_id}/imagery",
            headers=org.headers(),
            files={"file": (path.name, fh, "image/tiff")},
            data={"kind": kind, **{k: str(v) for k, v in form.items()}},
        )
    assert r.status_code == 201, r.text
    return r.json()


def test_real_landsat_multispectral_ndvi_cells_and_zones(
    client, org, imagery_dir, tmp_path
) -> None:
    src = member(LANDSAT_NC, tmp_path)
    with rasterio.open(src) as ds:
        crs, t = ds.crs, ds.transform
        red = ds.read(3, masked=True).astype(float)
        nir = ds.read(4, masked=True).astype(float)
        cx, cy = (ds.bounds.left + ds.bounds.right) / 2, (ds.bounds.bottom + ds.bounds.top) / 2
    pixel_ndvi = ((nir - red) / (nir + red)).filled(np.nan)
    # a 342 m x 228 m field (12 x 8 pixels) on the pixel grid near the scene's centre
    col0, row0 = (int(v) for v in ~t @ (cx, cy))
    x0, y1 = t @ (col0, row0)
    fid = _field(client, org, crs, x0, y1 - 228.0, 342.0, 228.0)
    img = _upload(client, org, fid, src, "multispectral", red_band=3, nir_band=4)
    assert img["bands"] == {"red": 3, "nir": 4} and img["band_count"] == 5
    assert img["resolution_m"] == pytest.approx(28.5, rel=0.01)
    assert img["overlap_share"] == pytest.approx(1.0)
    r = client.post(
        f"{API}/fields/{fid}/plans",
        headers=org.headers(),
        json={"swath_width_m": 2.3, "cell_length_m": 5.0, "heading": "longest_edge"},
    )
    assert r.status_code == 201, r.text
    plan = r.json()
    r = client.post(
        f"{API}/imagery/{img['id']}/prescriptions",
        headers=org.headers(),
        json={"plan_id": plan["id"]},
    )
    assert r.status_code == 201, r.text
    rx = r.json()
    assert rx["stats"]["no_data_count"] == 0
    cells = all_cells(client, org.headers(), rx["id"])
    assert len(cells) == plan["n_cells"]
    # Independent check: a cell that lies inside one Landsat pixel has that pixel's NDVI.
    to_src = Transformer.from_crs(4326, crs, always_xy=True)
    polys = shapely.transform(
        np.array([shape(c["geometry"]) for c in cells], dtype=object),
        lambda xy: np.column_stack(to_src.transform(xy[:, 0], xy[:, 1])),
    )
    ndvi = np.array([c["properties"]["source_value"] for c in cells], dtype=float)
    checked = 0
    for poly, v in zip(polys, ndvi, strict=True):
        xy = np.asarray(poly.exterior.coords)
        cols, rows = (xy[:, 0] - t.c) / t.a, (xy[:, 1] - t.f) / t.e  # north-up grid
        pc, pr = np.floor(cols).astype(int), np.floor(rows).astype(int)
        if (pc == pc[0]).all() and (pr == pr[0]).all():
            assert v == pytest.approx(pixel_ndvi[pr[0], pc[0]], abs=1e-4)
            checked += 1
    assert checked > 0.3 * len(cells)
    block = pixel_ndvi[row0 : row0 + 8, col0 : col0 + 12]
    assert np.nanmin(block) - 1e-4 <= ndvi.min() and ndvi.max() <= np.nanmax(block) + 1e-4
    assert np.nanmax(block) - np.nanmin(block) > 0.1  # real variation to zone
    r = client.post(
        f"{API}/imagery/{img['id']}/zones",
        headers=org.headers(),
        json={"plan_id": plan["id"], "k": 4, "min_area_m2": 300},
    )
    assert r.status_code == 201, r.text
    zones = r.json()["summary"]["interpolation"]["zones"]
    assert [z["zone"] for z in zones] == [1, 2, 3, 4]
    means = [z["mean_ndvi"] for z in zones]
    assert means == sorted(means) and sum(z["cells"] for z in zones) == len(cells)
    rates = {
        round(c["properties"]["rate_kg_ha"], 6)
        for c in all_cells(client, org.headers(), r.json()["id"])
    }
    assert len(rates) <= 4


def test_real_rgb_orthophoto_tiles_show_its_pixels(client, org, imagery_dir, tmp_path) -> None:
    import morecantile

    src = member(RGB_RMNP, tmp_path)
    with rasterio.open(src) as ds:
        cx, cy = (ds.bounds.left + ds.bounds.right) / 2, (ds.bounds.bottom + ds.bounds.top) / 2
    fid = _field(client, org, 4326, cx - 0.01, cy - 0.01, 0.02, 0.015)
    img = _upload(client, org, fid, src, "orthophoto")
    assert img["source_crs"] == "EPSG:4326" and img["bands"] == {"r": 1, "g": 2, "b": 3}
    tile = morecantile.tms.get("WebMercatorQuad").tile(cx, cy, 11)
    r = client.get(
        f"{API}/tiles/imagery/{img['id']}/{tile.z}/{tile.x}/{tile.y}.png", headers=org.headers()
    )
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    png = np.asarray(Image.open(io.BytesIO(r.content)).convert("RGBA"), dtype=float)
    opaque = png[..., 3] > 0
    assert opaque.mean() > 0.9  # the tile lies inside the image
    b = morecantile.tms.get("WebMercatorQuad").bounds(tile)
    with rasterio.open(src) as ds:
        win = window_from_bounds(b.left, b.bottom, b.right, b.top, ds.transform)
        ref = ds.read(window=win, masked=True).astype(float)
    for band in range(3):  # the tile's mean colour is the image's over the same ground
        assert png[..., band][opaque].mean() == pytest.approx(ref[band].mean(), abs=6.0)
