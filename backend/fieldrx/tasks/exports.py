"""Export and job-report tasks.

- ``export``: a job's as-applied file (per-cell CSV, zipped Shapefile, TASKDATA.zip;
  ``services.asapplied.export_job``) or a prescription version's file (GeoJSON, CSV,
  Shapefile, ISOXML; ``services.exports.export_version``). The bytes go to
  ``tasks.files`` and the task's result says where to download them
  (``GET /tasks/{id}/download``).
- ``report``: a job's as-applied report (``fleet.reports.build_report``, seed 001 eq.
  16-18). Its per-cell snapshot is stored as the task's file under the report's digest
  (``fleet.reports.report_digest``), and ``stored_report`` lets any API process answer
  the report (and the job's map tiles) from it instead of recomputing it.

Both run in a heavy-work child of the worker (``tasks.work``: killed on cancel within
about a second, ``FIELDRX_EXPORT_TIME_LIMIT_S`` at most) and follow the exactly-once
pattern of ``fieldrx.tasks``: the file is written and the task completed in one
transaction under the task's guard. Progress is reported by stage; a cancellation kills
the child and stores nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.models import Job, Prescription
from fieldrx.db.session import get_engine, raw_dsn
from fieldrx.fleet.reports import (
    JobReport,
    build_report,
    dump_report,
    load_report,
    report_digest,
    report_key,
)
from fieldrx.formats.export import JOB
from fieldrx.settings import get_settings
from fieldrx.tasks import files, store
from fieldrx.tasks.context import Progress, TaskInputError
from fieldrx.tasks.kinds import API, TASK_KINDS, TaskKind

Stage = Callable[[float, str], None]


def download_url(task_id: int) -> str:
    return f"{API}/tasks/{int(task_id)}/download"


def stored_report(
    session: Session, organisation_id: int, job_id: int, digest: str
) -> JobReport | None:
    """The snapshot of the job's report with this digest that a report task stored, if
    it is still kept (``files.purge_expired`` removes old ones: then it is recomputed)."""
    data = session.execute(
        text(
            "SELECT f.data FROM tasks t JOIN task_files f ON f.task_id = t.id "
            "WHERE t.organisation_id = :o AND t.kind = 'report' AND t.status = 'succeeded' "
            "AND t.result->>'job_id' = :j AND t.result->>'key' = :k "
            "ORDER BY t.id DESC LIMIT 1"
        ),
        {"o": organisation_id, "j": str(int(job_id)), "k": digest},
    ).scalar()
    return None if data is None else load_report(bytes(data))


def open_report_task(
    session: Session, organisation_id: int, job_id: int, digest: str
) -> int | None:
    """A report task of this job for this digest that is queued, running, or succeeded
    with its snapshot still kept: asking again joins it instead of queueing another."""
    return session.execute(
        text(
            "SELECT t.id FROM tasks t LEFT JOIN task_files f ON f.task_id = t.id "
            "WHERE t.organisation_id = :o AND t.kind = 'report' "
            "AND t.params->>'job_id' = :j AND t.params->>'key' = :k AND NOT t.cancel_requested "
            "AND (t.status IN ('queued', 'running') "
            "     OR (t.status = 'succeeded' AND f.task_id IS NOT NULL)) "
            "ORDER BY t.id DESC LIMIT 1"
        ),
        {"o": organisation_id, "j": str(int(job_id)), "k": digest},
    ).scalar()


def _job(session: Session, job_id: Any, org: int) -> Job:
    job = session.get(Job, int(job_id)) if job_id is not None else None
    if job is None or job.organisation_id != org:
        raise TaskInputError(f"job {job_id} not found (deleted after the task was queued?)")
    return job


def _scaled(progress: Stage, lo: float, hi: float) -> Stage:
    return lambda share, message: progress(lo + (hi - lo) * share, message)


def job_report(session: Session, job: Job, progress: Stage) -> tuple[JobReport, str]:
    """The job's report and its digest: a stored snapshot if one matches, else built."""
    digest = report_digest(report_key(session, job))
    rep = stored_report(session, job.organisation_id, job.id, digest)
    if rep is None:
        rep = build_report(session, job, progress=progress)
    return rep, digest


def _export_file(
    session: Session, p: dict[str, Any], org: int, progress: Stage
) -> tuple[bytes, str, str, dict[str, Any]]:
    """(bytes, media type, file name, extra result) of the export ``p`` describes."""
    if p.get("source") == JOB:
        from fieldrx.services.asapplied import export_job

        job = _job(session, p.get("job_id"), org)
        rep, _ = job_report(session, job, _scaled(progress, 0.05, 0.6))
        progress(0.65, f"writing the {p['format']} file")
        data, media, name = export_job(session, job, rep, p["format"])
        return data, media, name, {"job_id": job.id}
    from fieldrx.services import exports
    from fieldrx.services.prescriptions.versions import get_version

    rx = session.get(Prescription, int(p.get("rx_id") or 0))
    if rx is None or rx.organisation_id != org:
        raise TaskInputError(f"prescription {p.get('rx_id')} not found (deleted meanwhile?)")
    try:
        ver = get_version(session, rx, p.get("version"))
    except LookupError as exc:
        raise TaskInputError(str(exc)) from exc
    progress(0.2, f"writing the {p['format']} file")
    info: dict[str, Any] = {}
    data, media, name = exports.export_version(
        session,
        rx,
        ver,
        p["format"],
        profile=p.get("profile") or "cells",
        zone_classes=p.get("zone_classes"),
        max_polygons=p.get("max_polygons"),
        info=info,
    )
    extra: dict[str, Any] = {"prescription_id": rx.id, "version": ver.version}
    if "note" in info:
        extra["note"] = info["note"]
    return data, media, name, extra


def _stored(
    claimed: store.Claimed,
    work: Callable[[Session, Stage], tuple[bytes, str, str, dict[str, Any], str]],
) -> dict[str, Any]:
    """Run ``work`` (-> bytes, media, name, result, message) in one transaction under the
    task's guard, store its file and complete the task."""
    from fieldrx.services.bounded import ensure_caller_alive

    progress = Progress(raw_dsn(get_settings().database_url), claimed.id)
    try:
        with Session(get_engine()) as session:
            done = store.guard(session, claimed.id)
            if done is not None:
                return done
            data, media, name, result, message = work(session, progress)
            progress(0.95, "storing the file")
            f = files.put(session, claimed.id, claimed.organisation_id, data, media, name)
            result = {
                **result,
                "filename": f.filename,
                "media_type": f.media_type,
                "size": f.size,
                "download_url": download_url(claimed.id),
            }
            if not store.complete(session, claimed.id, result, message):
                session.rollback()
                return store.guard(session, claimed.id) or {}
            ensure_caller_alive("the task")  # its worker died: the retry stores it
            session.commit()
            return result
    finally:
        progress.close()


def run_export(claimed: store.Claimed, should_stop: Callable[[], bool]) -> dict[str, Any]:
    p = claimed.params

    def work(session: Session, progress: Stage) -> tuple[bytes, str, str, dict[str, Any], str]:
        data, media, name, extra = _export_file(session, p, claimed.organisation_id, progress)
        return data, media, name, extra, f"{name}: {len(data) / 1024**2:,.1f} MB"

    return _stored(claimed, work)


def run_report(claimed: store.Claimed, should_stop: Callable[[], bool]) -> dict[str, Any]:
    p = claimed.params

    def work(session: Session, progress: Stage) -> tuple[bytes, str, str, dict[str, Any], str]:
        job = _job(session, p.get("job_id"), claimed.organisation_id)
        rep, digest = job_report(session, job, _scaled(progress, 0.0, 0.9))
        result = {"job_id": job.id, "key": digest, "n_records": rep.n_records}
        name = f"job{job.id}_report.json.gz"
        return dump_report(rep), "application/gzip", name, result, f"{rep.n_records:,} records"

    return _stored(claimed, work)


def export_child(claimed: store.Claimed) -> dict[str, Any]:
    """An export task in a ``services.bounded`` child (file + completion, one transaction)."""
    return run_export(claimed, lambda: False)


def report_child(claimed: store.Claimed) -> dict[str, Any]:
    """A job-report task in a ``services.bounded`` child."""
    return run_report(claimed, lambda: False)


def _run_in_child(
    child: Callable[[store.Claimed], dict[str, Any]],
    what: str,
    claimed: store.Claimed,
    should_stop: Callable[[], bool],
) -> dict[str, Any]:
    """Exports and reports run in a child too: their stages (one report query, writing a
    large file) report no progress for many seconds, and in the worker thread a
    cancellation waited for the next stage (19 s); the child is killed within about a
    second of the cancel, like a plan's."""
    from fieldrx.services.bounded import run_bounded

    return run_bounded(
        child,
        claimed,
        time_limit_s=get_settings().export_time_limit_s,
        what=what,
        should_stop=should_stop,
    )


@TASK_KINDS.register
class ExportKind(TaskKind):
    """A file export; its result is the file's download."""

    name = "export"
    stores_file = True

    def result_url(self, result: dict[str, Any] | None) -> str | None:
        return None if not result else result.get("download_url")

    def run(self, claimed: store.Claimed, should_stop: Callable[[], bool]) -> dict[str, Any]:
        return _run_in_child(export_child, "the export", claimed, should_stop)


@TASK_KINDS.register
class ReportKind(TaskKind):
    name = "report"
    stores_file = True
    result_key, result_route = "job_id", "/jobs/{}/report"

    def run(self, claimed: store.Claimed, should_stop: Callable[[], bool]) -> dict[str, Any]:
        return _run_in_child(report_child, "the job report", claimed, should_stop)
