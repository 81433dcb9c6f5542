"""Imagery tiles: web-mercator PNGs, caching headers, and organisation scoping."""

from __future__ import annotations

import io
from pathlib import Path

import morecantile
import numpy as np
from PIL import Image
from pyproj import Transformer

from tests.imagery.rasters import UTM, X0, Y0, write_tiff

TMS = morecantile.tms.get("WebMercatorQuad")


def _centre_tile(z: int) -> morecantile.Tile:
    lon, lat = Transformer.from_crs(UTM, 4326, always_xy=True).transform(X0 + 100, Y0 + 50)
    return TMS.tile(lon, lat, z)


def _upload(client, org, field_id: int, path: Path, kind: str, **form: object) -> dict:  # noqa: ANN001
    with open(path, "rb") as fh:
        r = client.post(
            f"/api/v1/fields/{field_id}/imagery",
            headers=org.headers(),
            files={"file": (path.name, fh, "image/tiff")},
            data={"kind": kind, **{k: str(v) for k, v in form.items()}},
        )
    assert r.status_code == 201, r.text
    return r.json()


def test_orthophoto_tile_png_and_caching(client, org, field_id, imagery_dir, tmp_path) -> None:
    item = _upload(client, org, field_id, write_tiff(tmp_path / "o.tif"), "orthophoto")
    t = _centre_tile(18)
    url = f"/api/v1/tiles/imagery/{item['id']}/{t.z}/{t.x}/{t.y}.png"
    assert item["tiles"].format(z=t.z, x=t.x, y=t.y) == url
    r = client.get(url, headers=org.headers("viewer"))
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert "max-age" in r.headers["cache-control"] and r.headers["etag"]
    img = np.asarray(Image.open(io.BytesIO(r.content)))
    assert img.shape == (256, 256, 4)
    assert (img[..., 3] > 0).mean() > 0.3  # the tile holding the field centre shows the image
    assert img[..., 1].std() > 1  # the west-east gradient is visible (green band)
    again = client.get(url, headers={**org.headers(), "If-None-Match": r.headers["etag"]})
    assert again.status_code == 304
    far = TMS.tile(0.0, 0.0, 18)
    r = client.get(
        f"/api/v1/tiles/imagery/{item['id']}/18/{far.x}/{far.y}.png", headers=org.headers()
    )
    assert r.status_code == 204
    r = client.get(f"/api/v1/tiles/imagery/{item['id']}/3/9/0.png", headers=org.headers())
    assert r.status_code == 422


def test_other_organisation_gets_404(
    client, org, make_org, field_id, imagery_dir, tmp_path
) -> None:  # noqa: E501
    item = _upload(client, org, field_id, write_tiff(tmp_path / "o.tif"), "orthophoto")
    t = _centre_tile(17)
    url = f"/api/v1/tiles/imagery/{item['id']}/{t.z}/{t.x}/{t.y}.png"
    other = make_org()
    assert client.get(url, headers=other.headers()).status_code == 404
    assert client.get(f"/api/v1/imagery/{item['id']}", headers=other.headers()).status_code == 404
    assert client.get("/api/v1/imagery", headers=other.headers()).json()["total"] == 0
    assert (
        client.delete(f"/api/v1/imagery/{item['id']}", headers=other.headers()).status_code == 404
    )
    assert client.get(url).status_code == 401
    assert client.get(url, headers=org.headers()).status_code == 200


def test_ndvi_and_multispectral_tiles_colour_ramp(
    client, org, field_id, imagery_dir, tmp_path
) -> None:
    """NDVI rising west -> east renders red -> green, from a stored NDVI band and from
    (NIR - red) / (NIR + red) of a multispectral image alike."""
    nd = _upload(client, org, field_id, write_tiff(tmp_path / "n.tif", "ndvi"), "ndvi")
    ms = _upload(
        client,
        org,
        field_id,
        write_tiff(tmp_path / "m.tif", "multispectral"),
        "multispectral",
        red_band=3,
        nir_band=4,
    )
    t = _centre_tile(16)
    pngs = []
    for item in (nd, ms):
        r = client.get(
            f"/api/v1/tiles/imagery/{item['id']}/{t.z}/{t.x}/{t.y}.png", headers=org.headers()
        )
        assert r.status_code == 200, r.text
        img = np.asarray(Image.open(io.BytesIO(r.content)).convert("RGBA")).astype(int)
        cols = np.flatnonzero(img[..., 3].max(axis=0) > 0)
        assert len(cols) > 10
        row = img[:, :, 3].max(axis=1).argmax()
        west, east = img[row, cols[2]], img[row, cols[-3]]
        assert west[0] > west[1] and east[1] > east[0], (west, east)  # red west, green east
        pngs.append(img)
    assert np.abs(pngs[0] - pngs[1])[..., :3].mean() < 8  # same NDVI, same picture


def test_tiler_imported_with_the_router() -> None:
    """Regression: rio_tiler imported lazily inside the tile endpoint raced between thread-pool
    workers on a map's first concurrent tile requests (ImportError: partially initialised
    module rio_tiler.io -> 500). The router must import it up front."""
    import os
    import subprocess
    import sys

    code = "import sys, fieldrx.api.imagery; sys.exit(0 if 'rio_tiler.io' in sys.modules else 1)"
    r = subprocess.run([sys.executable, "-c", code], env=os.environ.copy(), check=False)
    assert r.returncode == 0, "fieldrx.api.imagery does not import rio_tiler at load time"
