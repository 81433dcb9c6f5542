"""Job packages on the tractor: pull with the device token, verify, cache, resume.

Everything the agent needs to work offline lives under one state directory:

    config.json              server URL and device token (mode 0600)
    jobs/<id>.json           the package exactly as downloaded (checksum verified)
    jobs/<id>.etag           the server's ETag, for cheap re-pulls
    progress/<id>.json       finished cells and how far a replayed source got
    queue.sqlite             telemetry queue (uplink.queue)

Every file is replaced atomically (write, fsync, rename), so a kill -9 or a
power cut leaves either the old or the new version, never a torn one.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Any

import httpx

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.protocol import ProtocolError

log = logging.getLogger(__name__)


def default_state_dir() -> Path:
    return Path(os.environ.get("FIELDRX_EDGE_HOME", Path.home() / ".fieldrx-edge"))


def atomic_write(path: Path, data: bytes, mode: int | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode or 0o644)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    dfd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


class JobStore:
    def __init__(self, root: str | Path | None = None) -> None:
        self.root = Path(root) if root is not None else default_state_dir()
        self.root.mkdir(parents=True, exist_ok=True)

    # config ---------------------------------------------------------------
    def save_config(self, server: str, token: str) -> None:
        self.set_config(server=server, token=token)

    def set_config(self, **values: Any) -> None:
        """Set keys of config.json (server, token, uplink), keeping the others."""
        body = json.dumps({**self.config(), **values}).encode()
        atomic_write(self.root / "config.json", body, mode=0o600)

    def config(self) -> dict[str, Any]:
        p = self.root / "config.json"
        return json.loads(p.read_text()) if p.exists() else {}

    # packages -------------------------------------------------------------
    def _pkg(self, job_id: int) -> Path:
        return self.root / "jobs" / f"{job_id}.json"

    def save_package(self, data: bytes, etag: str | None = None) -> JobPackage:
        """Verify (format + checksum) and cache; raises ProtocolError on a bad package."""
        pkg = JobPackage.from_json(data, verify=True)
        atomic_write(self._pkg(pkg.job_id), data)
        if etag:
            atomic_write(self._pkg(pkg.job_id).with_suffix(".etag"), etag.encode())
        return pkg

    def load(self, job_id: int) -> JobPackage:
        return JobPackage.from_json(self._pkg(job_id).read_bytes(), verify=True)

    def etag(self, job_id: int) -> str | None:
        p = self._pkg(job_id).with_suffix(".etag")
        return p.read_text() if p.exists() else None

    def job_ids(self) -> list[int]:
        d = self.root / "jobs"
        if not d.exists():
            return []
        return sorted(int(p.stem) for p in d.glob("*.json") if p.stem.isdigit())

    # progress -------------------------------------------------------------
    def _progress(self, job_id: int) -> Path:
        return self.root / "progress" / f"{job_id}.json"

    def load_progress(self, job_id: int) -> dict[str, Any]:
        p = self._progress(job_id)
        if not p.exists():
            return {"finished": [], "source_lines": 0, "state": "downloaded"}
        return json.loads(p.read_text())

    def save_progress(self, job_id: int, progress: dict[str, Any]) -> None:
        atomic_write(self._progress(job_id), json.dumps(progress).encode())

    def queue_path(self) -> Path:
        return self.root / "queue.sqlite"


def _job_ids_from_listing(obj: Any) -> list[int]:
    items = obj
    if isinstance(obj, dict):
        items = obj.get("jobs") or obj.get("items") or obj.get("features") or []
    ids = []
    for it in items:
        if isinstance(it, int):
            ids.append(it)
        elif isinstance(it, dict):
            v = it.get("id", it.get("job_id"))
            if v is None and isinstance(it.get("properties"), dict):
                v = it["properties"].get("id")
            if v is not None:
                ids.append(int(v))
    return ids


def pull(
    store: JobStore, server: str, token: str, client: httpx.Client | None = None
) -> dict[str, Any]:
    """Download every job of this machine; unchanged ones are skipped by ETag.

    Returns {"downloaded": [...], "unchanged": [...], "failed": {id: reason}}.
    """
    own = client is None
    c = client or httpx.Client(timeout=30.0)
    headers = {"Authorization": f"Bearer {token}"}
    base = server.rstrip("/")
    out: dict[str, Any] = {"downloaded": [], "unchanged": [], "failed": {}}
    try:
        resp = c.get(f"{base}/api/v1/device/jobs", headers=headers)
        resp.raise_for_status()
        for job_id in _job_ids_from_listing(resp.json()):
            h = dict(headers)
            etag = store.etag(job_id)
            if etag and store._pkg(job_id).exists():
                h["If-None-Match"] = etag
            r = c.get(f"{base}/api/v1/device/jobs/{job_id}/package", headers=h)
            if r.status_code == 304:
                out["unchanged"].append(job_id)
                continue
            if r.status_code != 200:
                out["failed"][job_id] = f"HTTP {r.status_code}"
                continue
            try:
                store.save_package(r.content, r.headers.get("ETag"))
            except ProtocolError as exc:
                out["failed"][job_id] = str(exc)
                continue
            out["downloaded"].append(job_id)
            try:
                c.post(
                    f"{base}/api/v1/device/jobs/{job_id}/state",
                    headers=headers,
                    json={"state": "downloaded"},
                )
            except httpx.HTTPError as exc:  # state is informative; the package is what matters
                log.info("could not report state of job %s: %s", job_id, exc)
    finally:
        if own:
            c.close()
    store.save_config(server, token)
    return out


def report_state(store: JobStore, job_id: int, state: str, timeout_s: float = 2.0) -> bool:
    """Best effort POST /device/jobs/{id}/state with the saved server and token."""
    cfg = store.config()
    if not cfg.get("server") or not cfg.get("token"):
        return False
    return post_state(cfg["server"], cfg["token"], job_id, state, timeout_s)


def post_state(server: str, token: str, job_id: int, state: str, timeout_s: float = 2.0) -> bool:
    """Best effort state report; offline is normal, so failures are only logged."""
    try:
        r = httpx.post(
            f"{server.rstrip('/')}/api/v1/device/jobs/{job_id}/state",
            headers={"Authorization": f"Bearer {token}"},
            json={"state": state},
            timeout=timeout_s,
        )
        if r.status_code >= 400:
            log.info("job %s state %s refused: %s %s", job_id, state, r.status_code, r.text)
        return r.status_code < 400
    except httpx.HTTPError as exc:
        log.info("job %s state %s not reported: %s", job_id, state, exc)
        return False
