"""Uploads spooled to disk for the heavy-work children, and what a crash left of them.

An upload that a child process parses (an ISOXML archive) is written to a private folder
in the system temp directory in 1 MiB chunks, never held whole in the server's memory; the
child inflates it from there. The folder is named after the server process
(``fieldrx-upload-<pid>-...``) and removed when the request ends, whatever its outcome.
A server killed outright cannot remove it, so every API and worker process removes, on
start, the folders whose process is no longer alive (``clean_orphans``, ``fieldrx.proctag``).
"""

from __future__ import annotations

import contextlib
import hashlib
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from fieldrx.errors import TooLarge
from fieldrx.proctag import process_tag, tag_alive, tag_of

PREFIX = "fieldrx-upload-"
CHUNK = 1 << 20


@contextlib.contextmanager
def spool_dir() -> Iterator[Path]:
    """A private folder for one request's uploads, removed when the block ends."""
    path = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{process_tag()}-"))
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


def spool(src: BinaryIO, dst: Path, limit: int, used: int = 0) -> tuple[int, str]:
    """Copy ``src`` to ``dst`` in chunks; returns (bytes, sha256 hex). ``TooLarge`` once
    ``used`` plus what was copied passes ``limit`` (the partial file is removed)."""
    digest = hashlib.sha256()
    n = 0
    with open(dst, "wb") as out:
        while chunk := src.read(CHUNK):
            n += len(chunk)
            if used + n > limit:
                out.close()
                dst.unlink(missing_ok=True)
                raise TooLarge(f"upload larger than {limit // 1024 // 1024} MB")
            digest.update(chunk)
            out.write(chunk)
    return n, digest.hexdigest()


def clean_orphans(base: Path | None = None) -> list[Path]:
    """Remove the spool folders of processes that are gone (a crash or ``kill -9``)."""
    root = Path(base or tempfile.gettempdir())
    removed = []
    for d in root.glob(f"{PREFIX}*"):
        tag = tag_of(d.name[len(PREFIX) :])
        if d.is_dir() and tag is not None and not tag_alive(tag):
            shutil.rmtree(d, ignore_errors=True)
            removed.append(d)
    return removed
