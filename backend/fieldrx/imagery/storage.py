"""Where COGs live: one directory (``FIELDRX_IMAGERY_DIR``), one sub-directory per
organisation, random file names; uploads are received in ``.incoming/`` beside them so a
rename into place never crosses a file system. Object storage can replace this module."""

from __future__ import annotations

import uuid
from collections.abc import Iterable
from pathlib import Path

from fieldrx.settings import get_settings


def root() -> Path:
    configured = get_settings().imagery_dir
    base = (
        Path(configured) if configured else Path(__file__).resolve().parents[3] / "var" / "imagery"
    )
    base.mkdir(parents=True, exist_ok=True)
    return base


def new_key(organisation_id: int) -> str:
    """A fresh storage key (relative path) for a COG of this organisation."""
    return f"org{int(organisation_id)}/{uuid.uuid4().hex}.tif"


def path_for(key: str) -> Path:
    base = root().resolve()
    path = (base / key).resolve()
    if base not in path.parents:
        raise ValueError(f"storage key {key!r} leaves the imagery directory")
    return path


def incoming_path() -> Path:
    d = root() / ".incoming"
    d.mkdir(parents=True, exist_ok=True)
    return d / f"{uuid.uuid4().hex}.upload"


def remove(keys: Iterable[str]) -> None:
    """Delete the COGs of rows that are gone (missing files are fine)."""
    for key in keys:
        path_for(key).unlink(missing_ok=True)
