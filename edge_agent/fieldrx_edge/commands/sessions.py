"""How a command opens and closes its job session (``session.JobSession``): the simulator's
and the tractor's, with the cab display attached when ``--cab`` asks. Shared by
``simulate``, ``run`` and the sensor kinds' commands (``kinds``)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobs import JobStore
from fieldrx_edge.session import JobSession, UplinkOptions


def sim_session(a: argparse.Namespace, job: JobPackage, profile: str = "full") -> JobSession:
    """The simulation's session: with ``--server`` the records go through the durable queue
    and the HTTP uplink exactly as ``run``'s (queue in --state-dir, else a temporary dir);
    with ``--cab`` the display watches it."""
    if a.server and not a.token:
        raise SystemExit("--server needs --token")
    opts = dataclasses.replace(UplinkOptions.from_args(a), profile=profile)
    qdir = Path(a.state_dir) if a.state_dir else None
    session = JobSession(job, opts, qdir / "queue.sqlite" if qdir else None)
    from fieldrx_edge.cab.server import attach_cab

    attach_cab(a, session, JobStore(a.state_dir) if a.state_dir else None)
    return session


def session_report(session: JobSession, out: dict[str, Any]) -> None:
    """Close the session (drain, job completed) and add its figures to ``out``."""
    has_uplink = session.sender is not None
    up = session.close(completed=has_uplink)
    if has_uplink:
        out["telemetry_drained"] = up["drained"]
        out["telemetry"] = up["queue"]
        out["uplink"] = up["uplink"]
        out["job_state_reported"] = up.get("job_state_reported", False)


def finished_early(a: argparse.Namespace, session: JobSession, pair: Any = None) -> int:
    """The operator pressed Finish before the path's end: the job is not completed (it is
    left running on the server); what was queued is sent, and the figures say so."""
    if pair is not None:
        pair.close()
    up = session.close(completed=False)
    out = {
        "job_id": session.job.job_id if session.job else None,
        "finished_early": True,
        "records": session.records,
        "telemetry_drained": up["drained"],
        "telemetry": up["queue"],
    }
    print(json.dumps(out), flush=True)
    if session.cab is not None:
        session.cab.finish()
    return 0


def open_session(a: argparse.Namespace, job: JobPackage, store: JobStore, profile: str) -> Any:
    """The job's session in the state dir, with the cab display when ``--cab`` asks."""
    opts = dataclasses.replace(UplinkOptions.from_args(a, store), profile=profile)
    session = JobSession(job, opts, store.queue_path())
    from fieldrx_edge.cab.server import attach_cab

    attach_cab(a, session, store)
    return session
