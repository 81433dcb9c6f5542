"""Imagery ingest in the background ("large uploads are processed in the
background with progress"): a large upload answers 202 with a task, a worker converts it
(here ``tasks.work.execute``, what ``fieldrx worker`` runs), the task links the image;
hostile input fails the task with the inline message and leaves nothing behind."""

from __future__ import annotations

from pathlib import Path

import pytest
from fieldrx.db.models import Imagery
from sqlalchemy import func, select

from tests.imagery.conftest import stored_files
from tests.imagery.rasters import write_tiff


def _upload(client, org, field_id: int, path: Path, kind: str, query: str = ""):  # noqa: ANN202
    with open(path, "rb") as fh:
        return client.post(
            f"/api/v1/fields/{field_id}/imagery{query}",
            headers=org.headers(),
            files={"file": (path.name, fh, "image/tiff")},
            data={"kind": kind},
        )


def _rows(db, org) -> int:  # noqa: ANN001
    db.rollback()
    return db.scalar(select(func.count()).where(Imagery.organisation_id == org.id))


def test_background_upload_is_converted_by_a_task(
    client, org, field_id, imagery_dir, tmp_path, db
) -> None:
    from fieldrx.tasks.work import execute

    src = write_tiff(tmp_path / "ortho.tif", "orthophoto")
    r = _upload(client, org, field_id, src, "orthophoto", "?background=true")
    assert r.status_code == 202, r.text
    task = r.json()
    assert task["kind"] == "imagery" and task["status"] == "queued"
    waiting = stored_files(imagery_dir)
    assert [p.parent.name for p in waiting] == [".incoming"]  # the upload waits for a worker
    assert _rows(db, org) == 0

    execute(task["id"])
    got = client.get(task["url"], headers=org.headers()).json()
    assert got["status"] == "succeeded", got
    assert got["result"]["overlap_share"] == pytest.approx(1.0)
    item = client.get(got["result_url"], headers=org.headers()).json()
    assert item["kind"] == "orthophoto" and item["field_id"] == field_id
    assert item["filename"] == "ortho.tif" and (item["width"], item["height"]) == (440, 240)
    files = stored_files(imagery_dir)
    assert len(files) == 1 and files[0].parent.name == f"org{org.id}"  # upload removed
    assert _rows(db, org) == 1


def test_large_upload_goes_to_the_background_by_itself(
    client, org, field_id, imagery_dir, tmp_path, monkeypatch
) -> None:
    from fieldrx.settings import get_settings

    src = write_tiff(tmp_path / "ortho.tif", "orthophoto")
    monkeypatch.setenv("FIELDRX_IMAGERY_BACKGROUND_BYTES", str(src.stat().st_size - 1))
    get_settings.cache_clear()
    assert _upload(client, org, field_id, src, "orthophoto").status_code == 202
    assert _upload(client, org, field_id, src, "orthophoto", "?background=false").status_code == 201
    monkeypatch.setenv("FIELDRX_IMAGERY_BACKGROUND_BYTES", str(src.stat().st_size))
    get_settings.cache_clear()
    assert _upload(client, org, field_id, src, "orthophoto").status_code == 201


def test_hostile_background_upload_fails_the_task_and_leaves_nothing(
    client, org, field_id, imagery_dir, tmp_path, db
) -> None:
    from fieldrx.tasks.work import execute

    fake = tmp_path / "photo.tif"
    fake.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 4096)
    r = _upload(client, org, field_id, fake, "orthophoto", "?background=true")
    assert r.status_code == 202, r.text
    execute(r.json()["id"])
    got = client.get(r.json()["url"], headers=org.headers()).json()
    assert got["status"] == "failed" and "not a TIFF" in got["error"]
    assert got["result_url"] is None
    assert stored_files(imagery_dir) == [] and _rows(db, org) == 0
