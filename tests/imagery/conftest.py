"""Imagery fixtures: a private storage directory per test and a field to upload onto."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.imagery.rasters import field_geojson
from tests.support import feature


@pytest.fixture()
def imagery_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, database_url: str) -> Path:
    from fieldrx.settings import get_settings

    d = tmp_path / "imagery"
    monkeypatch.setenv("FIELDRX_IMAGERY_DIR", str(d))
    get_settings.cache_clear()
    yield d
    get_settings.cache_clear()


@pytest.fixture()
def field_id(client, org) -> int:  # noqa: ANN001
    r = client.post("/api/v1/fields", headers=org.headers(), json=feature(field_geojson()))
    assert r.status_code == 201, r.text
    return r.json()["id"]


def stored_files(d: Path) -> list[Path]:
    """Every file under the imagery directory (uploads in flight included)."""
    return sorted(p for p in d.rglob("*") if p.is_file()) if d.exists() else []
