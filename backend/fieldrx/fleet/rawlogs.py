"""The full 10 Hz logs of thin-profile jobs, uploaded on request.

A thin tractor keeps every fix in its own log (``fieldrx_edge.uplink.thin.RawLog``)
and sends it, one gzip file per job, when the office asks for it: the office
requests it (a ``.requested`` marker beside where the file will be), the agent
lists the requests (``fieldrx-edge upload-log``) and uploads. Files live in one
directory (``FIELDRX_RAW_LOG_DIR``), one sub-directory per organisation; an
upload is written beside its place and renamed into it, so a reader never sees
half a file. Object storage can replace this module.
"""

from __future__ import annotations

import gzip
import os
import uuid
import zlib
from pathlib import Path

from fieldrx.settings import get_settings


def root() -> Path:
    configured = get_settings().raw_log_dir
    base = (
        Path(configured) if configured else Path(__file__).resolve().parents[3] / "var" / "rawlogs"
    )
    base.mkdir(parents=True, exist_ok=True)
    return base


def log_path(organisation_id: int, job_id: int) -> Path:
    return root() / f"org{int(organisation_id)}" / f"job-{int(job_id)}.jsonl.gz"


def _marker(organisation_id: int, job_id: int) -> Path:
    return log_path(organisation_id, job_id).with_suffix(".requested")


def request(organisation_id: int, job_id: int) -> None:
    m = _marker(organisation_id, job_id)
    m.parent.mkdir(parents=True, exist_ok=True)
    m.touch()


def requested(organisation_id: int, job_id: int) -> bool:
    return _marker(organisation_id, job_id).exists()


def store(organisation_id: int, job_id: int, body: bytes) -> int:
    """Check that ``body`` is a whole gzip file of JSON lines and put it in place; the
    request is then answered. Returns the number of lines (fixes). ValueError says why not."""
    try:
        data = gzip.decompress(body)
    except (OSError, EOFError, zlib.error) as exc:
        raise ValueError(f"the raw log is not a whole gzip file: {exc}") from exc
    if data and not data.endswith(b"\n"):
        raise ValueError("the raw log's last line is cut short")
    lines = data.count(b"\n")
    dst = log_path(organisation_id, job_id)
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{uuid.uuid4().hex}.upload")
    tmp.write_bytes(body)
    os.replace(tmp, dst)
    _marker(organisation_id, job_id).unlink(missing_ok=True)
    return lines
