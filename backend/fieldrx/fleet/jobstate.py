"""Job state machine: planned -> sent -> downloaded -> running <-> paused -> completed | aborted.

Every change is a ``job_events`` row (when, and who: a user or a machine) and a
live message. Asking for the state a job is already in is a no-op (a device
that restarts may repeat "running"); anything else not in the table is a 409.

A job that ends "completed" while prescribed cells received nothing raises a
``cells_not_applied`` alert listing them (a job ended "completed" at
85.7 % coverage with no alert); the report lists them too (``not_applied_seqs``).
"""

from __future__ import annotations

import datetime as dt
import json
from typing import Any

from fieldrx_edge.jobkinds.registry import kind_of
from sqlalchemy import select, text
from sqlalchemy.orm import Session

from fieldrx.db.models import Alert, Job, JobEvent
from fieldrx.errors import Conflict, Invalid
from fieldrx.fleet.alerts import LIVE_CHANNEL, alert_message
from fieldrx.fleet.reports import build_report
from fieldrx.jobkinds.registry import hooks

FINAL = ("completed", "aborted")
TRANSITIONS: dict[str, tuple[str, ...]] = {
    "planned": ("sent", "aborted"),
    "sent": ("downloaded", "aborted"),
    "downloaded": ("running", "aborted"),
    "running": ("paused", "completed", "aborted"),
    "paused": ("running", "completed", "aborted"),
    "completed": (),
    "aborted": (),
}
DEVICE_STATES = ("downloaded", "running", "paused", "completed")


def lock_job(session: Session, job: Job) -> None:
    """Re-read ``job`` under a row lock (its state changes one at a time).

    The lock names the job's machine as well as its id: past one node (Citus) a row lock
    on a distributed table must name the distribution column to reach one shard
    (``SELECT ... FOR UPDATE`` by id alone is refused there)."""
    session.execute(
        select(Job)
        .where(Job.machine_id == job.machine_id, Job.id == job.id)
        .with_for_update()
        .execution_options(populate_existing=True)
    ).scalar_one()


def change_state(
    session: Session,
    job: Job,
    state: str,
    *,
    user_id: int | None = None,
    machine_id: int | None = None,
    note: str = "",
) -> bool:
    """Apply a transition (not committed); False when the job already is in ``state``."""
    if state not in TRANSITIONS:
        raise Invalid(f"unknown state '{state}'", where="state", allowed=list(TRANSITIONS))
    if job.state == state:
        return False
    allowed = TRANSITIONS[job.state]
    if state not in allowed:
        hint = f"allowed: {', '.join(allowed)}" if allowed else f"'{job.state}' is final"
        raise Conflict(
            f"job {job.id} cannot go from '{job.state}' to '{state}' ({hint})",
            state=job.state,
            allowed=list(allowed),
        )
    job.state = state
    job.updated_at = dt.datetime.now(dt.UTC)
    session.add(
        JobEvent(
            job_id=job.id,
            machine_id=job.machine_id,
            state=state,
            by_user_id=user_id,
            by_machine_id=machine_id,
            note=note,
        )
    )
    notify_job(session, job)
    if state == "completed" and kind_of(job.kind).rates_from == "cells":
        alert_cells_not_applied(session, job)
    elif state == "completed":
        end = hooks(job.kind).job_end  # a sensor kind's own end-of-job check
        if end is not None:
            end(session, job)
    return True


LISTED_SEQS = 50  # seqs spelled out in the alert's message; the report lists them all


def alert_cells_not_applied(session: Session, job: Job) -> Alert | None:
    """The job-end check: an alert listing the prescribed cells nothing landed in.

    The alert is an event (it starts and ends when the job ends); it stays in the
    list until someone acknowledges it. None when every prescribed cell got fertilizer.
    """
    session.flush()
    seqs = build_report(session, job).not_applied_seqs
    if not seqs:
        return None
    shown = ", ".join(str(s) for s in seqs[:LISTED_SEQS])
    more = f" and {len(seqs) - LISTED_SEQS} more" if len(seqs) > LISTED_SEQS else ""
    now = dt.datetime.now(dt.UTC)
    a = Alert(
        organisation_id=job.organisation_id,
        machine_id=job.machine_id,
        job_id=job.id,
        kind="cells_not_applied",
        message=f"job ended with {len(seqs)} prescribed cells never applied: seq {shown}{more}",
        value=float(len(seqs)),
        started_at=now,
        ended_at=now,
    )
    session.add(a)
    session.flush()
    msg = alert_message(
        job.organisation_id, a.id, job.machine_id, a.kind, "started", a.message, a.value, job.id
    )
    msg["seqs"] = seqs[:LISTED_SEQS]
    session.execute(text("SELECT pg_notify(:c, :p)"), {"c": LIVE_CHANNEL, "p": json.dumps(msg)})
    return a


def notify_job(session: Session, job: Job) -> None:
    msg: dict[str, Any] = {
        "type": "job",
        "org": job.organisation_id,
        "job_id": job.id,
        "machine_id": job.machine_id,
        "state": job.state,
        "cells_applied": job.cells_applied,
        "n_cells": job.n_cells,
        "progress": job.cells_applied / job.n_cells if job.n_cells else 0.0,
    }
    session.execute(text("SELECT pg_notify(:c, :p)"), {"c": LIVE_CHANNEL, "p": json.dumps(msg)})
