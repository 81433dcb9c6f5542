"""Imagery upload: GeoTIFF in any CRS -> COG in storage; hostile input is a 422 that leaves
nothing behind (no file, no row)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from fieldrx.db.models import Imagery
from pyproj import Transformer
from sqlalchemy import func, select

from tests.imagery.conftest import stored_files
from tests.imagery.rasters import UTM, X0, Y0, write_tiff


def _upload(client, org, field_id: int, path: Path, kind: str, **form: object):  # noqa: ANN202
    with open(path, "rb") as fh:
        return client.post(
            f"/api/v1/fields/{field_id}/imagery",
            headers=org.headers(),
            files={"file": (path.name, fh, "image/tiff")},
            data={"kind": kind, **{k: str(v) for k, v in form.items()}},
        )


def _rows(db, org) -> int:  # noqa: ANN001
    db.rollback()
    return db.scalar(select(func.count()).where(Imagery.organisation_id == org.id))


def test_orthophoto_utm_becomes_cog(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    src = write_tiff(
        tmp_path / "ortho.tif", "orthophoto", tags={"TIFFTAG_DATETIME": "2026:05:14 10:31:00"}
    )
    r = _upload(client, org, field_id, src, "orthophoto")
    assert r.status_code == 201, r.text
    item = r.json()
    assert item["kind"] == "orthophoto" and item["bands"] == {"r": 1, "g": 2, "b": 3}
    assert item["resolution_m"] == pytest.approx(0.5, rel=1e-3)
    assert item["acquired_on"] == "2026-05-14"
    assert item["overlap_share"] == pytest.approx(1.0)
    assert (item["width"], item["height"]) == (440, 240)
    files = stored_files(imagery_dir)
    assert len(files) == 1 and files[0].suffix == ".tif"  # the upload itself is gone
    with rasterio.open(files[0]) as cog:
        assert cog.profile["tiled"]
        assert cog.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        assert cog.crs.to_epsg() == 3857  # orthophotos: stored on the web-map tile grid
    listed = client.get(f"/api/v1/fields/{field_id}/imagery", headers=org.headers()).json()
    assert [i["id"] for i in listed["items"]] == [item["id"]]
    assert _rows(db, org) == 1
    assert client.delete(f"/api/v1/imagery/{item['id']}", headers=org.headers()).status_code == 204
    assert stored_files(imagery_dir) == [] and _rows(db, org) == 0


def test_ndvi_in_wgs84_with_given_date(client, org, field_id, imagery_dir, tmp_path) -> None:
    tr = Transformer.from_crs(UTM, 4326, always_xy=True)
    w, s = tr.transform(X0 - 20, Y0 - 20)
    e, n = tr.transform(X0 + 220, Y0 + 120)
    src = write_tiff(
        tmp_path / "ndvi.tif", "ndvi", crs=4326, bounds=(w, s, e, n), res=(e - w) / 480
    )
    r = _upload(client, org, field_id, src, "ndvi", acquired_on="2026-06-01")
    assert r.status_code == 201, r.text
    item = r.json()
    assert item["source_crs"] == "EPSG:4326" and item["acquired_on"] == "2026-06-01"
    (cog,) = stored_files(imagery_dir)
    with rasterio.open(cog) as ds:  # analysis imagery keeps its own pixel grid
        assert ds.crs.to_epsg() == 4326 and (ds.width, ds.height) == (item["width"], item["height"])
    assert 0.3 < item["resolution_m"] < 0.8
    lon, lat = tr.transform(X0 + 100, Y0 + 50)
    b = item["bounds"]
    assert b[0] < lon < b[2] and b[1] < lat < b[3]


def test_multispectral_named_bands(client, org, field_id, imagery_dir, tmp_path) -> None:
    src = write_tiff(tmp_path / "ms.tif", "multispectral")
    r = _upload(client, org, field_id, src, "multispectral")
    assert r.status_code == 422 and "red_band and nir_band" in r.json()["detail"]
    r = _upload(client, org, field_id, src, "multispectral", red_band=3, nir_band=9)
    assert r.status_code == 422 and "nir_band 9 does not exist" in r.json()["detail"]
    assert stored_files(imagery_dir) == []
    r = _upload(client, org, field_id, src, "multispectral", red_band=3, nir_band=4)
    assert r.status_code == 201, r.text
    assert r.json()["bands"] == {"red": 3, "nir": 4}


def _assert_rejected(r, text: str, imagery_dir: Path, db, org) -> None:  # noqa: ANN001
    assert r.status_code == 422, r.text
    assert text in r.json()["detail"], r.json()
    assert r.json().get("where") == "file"
    assert stored_files(imagery_dir) == [], "a rejected upload left files behind"
    assert _rows(db, org) == 0


def test_not_georeferenced(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    src = write_tiff(tmp_path / "plain.tif", crs=None)
    r = _upload(client, org, field_id, src, "orthophoto")
    _assert_rejected(r, "not georeferenced", imagery_dir, db, org)


def test_non_tiff_renamed(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    png = tmp_path / "photo.tif"
    with rasterio.open(png, "w", driver="PNG", width=8, height=8, count=3, dtype="uint8") as d:
        d.write(np.zeros((3, 8, 8), "uint8"))
    r = _upload(client, org, field_id, png, "orthophoto")
    _assert_rejected(r, "not a TIFF", imagery_dir, db, org)


def test_truncated_tiff(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    src = write_tiff(tmp_path / "ok.tif")
    bad = tmp_path / "bad.tif"
    data = src.read_bytes()
    bad.write_bytes(data[: len(data) // 2])  # header and tile index intact, pixels cut off
    r = _upload(client, org, field_id, bad, "orthophoto")
    _assert_rejected(r, "cannot be", imagery_dir, db, org)


def test_huge_header_claim(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    """A few-KB sparse TIFF whose header claims 100,000 x 100,000 x 2 (20 GB)."""
    src = write_tiff(
        tmp_path / "claim.tif",
        bounds=(X0, Y0, X0 + 10_000, Y0 + 10_000),
        res=0.1,
        count=2,
        skip_write=True,
    )
    assert src.stat().st_size < 2 * 1024 * 1024  # only the header and its tile index
    r = _upload(client, org, field_id, src, "ndvi")
    _assert_rejected(r, "100000 x 100000 pixels", imagery_dir, db, org)


def test_no_overlap(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    src = write_tiff(tmp_path / "far.tif", bounds=(X0 + 5000, Y0, X0 + 5100, Y0 + 100))
    r = _upload(client, org, field_id, src, "orthophoto")
    _assert_rejected(r, "does not overlap the field", imagery_dir, db, org)


def test_band_mismatch(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    src = write_tiff(tmp_path / "rgb.tif", "orthophoto")
    r = _upload(client, org, field_id, src, "ndvi")
    _assert_rejected(r, "exactly 1 band, the file has 3", imagery_dir, db, org)
    one = write_tiff(tmp_path / "one.tif", "ndvi")
    r = _upload(client, org, field_id, one, "orthophoto")
    _assert_rejected(r, "3 (RGB) or 4 (RGBA) bands, the file has 1", imagery_dir, db, org)


def test_decompression_bomb_is_stopped(
    client, org, field_id, imagery_dir, tmp_path, db, monkeypatch
) -> None:
    """A tiny file that expands to 400 M pixels: refused by the conversion budget before any
    decoding (it used to be converted until the time limit killed it)."""
    import time

    src = write_tiff(
        tmp_path / "bomb.tif", bounds=(X0, Y0, X0 + 2000, Y0 + 2000), res=0.1, skip_write=True
    )
    assert src.stat().st_size < 1024 * 1024
    t0 = time.monotonic()
    r = _upload(client, org, field_id, src, "orthophoto")
    _assert_rejected(r, "times its file size", imagery_dir, db, org)
    assert time.monotonic() - t0 < 30


def test_deflate_bomb_of_zeros_is_refused_quickly(
    client, org, field_id, imagery_dir, tmp_path, db
) -> None:
    """Dense DEFLATE zeros (~1000:1, under the pixel limit) kept a converter busy for
    minutes; the budget (declared bytes per file byte) refuses them before decoding."""
    import time

    path = tmp_path / "zeros.tif"
    w = h = 6000
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
        "transform": rasterio.transform.from_bounds(X0, Y0, X0 + 600, Y0 + 600, w, h),
    }
    with rasterio.open(path, "w", **meta) as dst:
        dst.write(np.zeros((h, w), "float32"), 1)
    assert path.stat().st_size * 300 < w * h * 4
    t0 = time.monotonic()
    r = _upload(client, org, field_id, path, "ndvi")
    _assert_rejected(r, "times its file size", imagery_dir, db, org)
    assert time.monotonic() - t0 < 30


def test_errors_never_name_server_files(client, org, field_id, imagery_dir, tmp_path, db) -> None:
    """GDAL's messages name the file it read: the server's temporary upload path must not
    reach the user."""
    bad = tmp_path / "garbage.tif"
    bad.write_bytes(b"II*\x00" + b"\xff" * 4000)
    r = _upload(client, org, field_id, bad, "orthophoto")
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert ".upload" not in detail and str(imagery_dir) not in detail and "/tmp" not in detail
    assert stored_files(imagery_dir) == []


def test_conversions_take_a_heavy_work_slot(
    client, org, field_id, imagery_dir, tmp_path, monkeypatch
) -> None:
    """Imagery conversions go through the same bounded slots as planning and imports (each
    upload used to start its own converter, outside them): with every slot taken the upload
    waits, then gets 503 + Retry-After and leaves nothing behind."""
    from fieldrx.services import bounded
    from fieldrx.settings import get_settings

    monkeypatch.setattr(get_settings(), "import_time_limit_s", 1.0)
    src = write_tiff(tmp_path / "ok.tif")
    slots = bounded.get_slots()  # the test holds every slot of this process
    held = 0
    while slots.acquire(blocking=False):
        held += 1
    try:
        r = _upload(client, org, field_id, src, "orthophoto")
    finally:
        for _ in range(held):
            slots.release()
    assert r.status_code == 503, r.text
    assert r.headers["retry-after"]
    assert stored_files(imagery_dir) == []
    assert _upload(client, org, field_id, src, "orthophoto").status_code == 201


def test_other_org_cannot_upload(client, org, make_org, field_id, imagery_dir, tmp_path) -> None:
    other = make_org()
    src = write_tiff(tmp_path / "o.tif")
    r = _upload(client, other, field_id, src, "orthophoto")
    assert r.status_code == 404
    assert stored_files(imagery_dir) == []


def test_deleting_the_field_removes_its_cogs(
    client, org, field_id, imagery_dir, tmp_path, db
) -> None:
    """Regression: imagery rows went with the field (ON DELETE CASCADE) but their COG files
    stayed in storage forever."""
    _upload(client, org, field_id, write_tiff(tmp_path / "o.tif"), "orthophoto")
    assert len(stored_files(imagery_dir)) == 1
    assert client.delete(f"/api/v1/fields/{field_id}", headers=org.headers()).status_code == 204
    assert stored_files(imagery_dir) == [] and _rows(db, org) == 0


def test_imagery_uploads_are_not_capped_at_the_generic_upload_limit(
    client,
    org,
    field_id,
    imagery_dir,
    tmp_path,
    db,  # noqa: ANN001
) -> None:
    """An orthophoto is often larger than the 51 MiB cap of other uploads: the imagery route
    has its own limit (FIELDRX_IMAGERY_MAX_UPLOAD_BYTES), so a 60 MiB file reaches the
    validator (a clear 422: not a TIFF) instead of a 413 from the body-size middleware,
    and leaves nothing behind."""
    from fieldrx.settings import get_settings

    assert get_settings().max_upload_bytes < 60 * 2**20 < get_settings().imagery_max_upload_bytes
    big = tmp_path / "big.tif"
    with open(big, "wb") as fh:
        fh.write(b"not a tiff" + b"\0" * (60 * 2**20))
    r = _upload(client, org, field_id, big, "orthophoto")
    assert r.status_code == 422, r.text[:300]
    assert "TIFF" in r.text
    assert stored_files(imagery_dir) == [] and _rows(db, org) == 0
    # other uploads keep the generic cap
    r = client.post(
        "/api/v1/fields/import",
        headers=org.headers(),
        files={"file": ("big.zip", big.read_bytes(), "application/zip")},
    )
    assert r.status_code == 413, r.text[:300]
