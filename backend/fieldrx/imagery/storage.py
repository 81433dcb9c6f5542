"""Where COGs live: one directory (``FIELDRX_IMAGERY_DIR``), one sub-directory per
organisation, random file names; uploads are received in ``.incoming/`` beside them so a
rename into place never crosses a file system. Object storage can replace this module.

New COGs and received uploads are named after the process that writes them
(``fieldrx.proctag``), so ``orphans`` can tell what a killed server or worker left (its
process is gone and no row or open task names the file) from what a live one is still
writing."""

from __future__ import annotations

import uuid
from collections.abc import Iterable
from pathlib import Path

from fieldrx.proctag import process_tag, tag_alive, tag_of
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
    return f"org{int(organisation_id)}/{process_tag()}-{uuid.uuid4().hex}.tif"


def path_for(key: str) -> Path:
    base = root().resolve()
    path = (base / key).resolve()
    if base not in path.parents:
        raise ValueError(f"storage key {key!r} leaves the imagery directory")
    return path


def incoming_path() -> Path:
    d = root() / ".incoming"
    d.mkdir(parents=True, exist_ok=True)
    return d / f"{process_tag()}-{uuid.uuid4().hex}.upload"


def remove(keys: Iterable[str]) -> None:
    """Delete the COGs of rows that are gone (missing files are fine)."""
    for key in keys:
        path_for(key).unlink(missing_ok=True)


def orphans(stored_keys: set[str], open_uploads: set[str]) -> list[Path]:
    """Files and work folders written by processes that are gone and named by nothing:
    COGs no imagery row stores (``stored_keys``), received uploads no open task converts
    (``open_uploads``: their names), conversion work folders."""
    base = root().resolve()
    out: list[Path] = []
    for path in base.glob("*/*"):
        name = path.name
        if path.parent.name == ".incoming":
            tag = tag_of(name)
            if name in open_uploads:
                continue
        elif name.startswith(".work-"):
            tag = tag_of(name[len(".work-") :])
        else:
            tag = tag_of(name)
            if path.relative_to(base).as_posix() in stored_keys:
                continue
        if tag is not None and not tag_alive(tag):
            out.append(path)
    return out
