"""On start, the API and every worker remove what a crashed (``kill -9``) process left:
spooled uploads (``services.spool``), received imagery no open task converts, COGs no row
stores and conversion work folders (``imagery.storage.orphans``). Only files of
processes that are gone are touched (``fieldrx.proctag``), so a live server or worker
sharing the folders keeps what it is writing."""

from __future__ import annotations

import logging
import shutil

from sqlalchemy import text
from sqlalchemy.engine import Engine

from fieldrx.imagery import storage
from fieldrx.services import spool

log = logging.getLogger(__name__)


def clean_after_crash(engine: Engine) -> int:
    """Remove the leftovers (see module docstring); the number of paths removed."""
    removed = len(spool.clean_orphans())
    with engine.connect() as conn:
        keys = set(conn.execute(text("SELECT storage_key FROM imagery")).scalars())
        uploads = set(
            conn.execute(
                text(
                    # any open task that holds an upload, whatever its kind (tasks.kinds)
                    "SELECT params->>'incoming' FROM tasks WHERE params->>'incoming' IS NOT NULL "
                    "AND status IN ('queued', 'running')"
                )
            ).scalars()
        )
    for path in storage.orphans(keys, uploads):
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed += 1
    if removed:
        log.info("removed %d file(s) left by stopped processes", removed)
    return removed


def clean_after_crash_logged(engine: Engine) -> None:
    """``clean_after_crash`` that never stops a start (a database not up yet: next start)."""
    try:
        clean_after_crash(engine)
    except Exception:  # noqa: BLE001 - cleaning must not keep the server from starting
        log.warning("cleaning what stopped processes left failed", exc_info=True)
