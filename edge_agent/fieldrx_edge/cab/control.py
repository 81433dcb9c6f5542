"""The screen's buttons acting on the one job session: start, pause (meter off), resume,
finish, rate override, sections, alarm acknowledgement, the tank's starting mass; and the
cached jobs list the job screen shows."""

from __future__ import annotations

import threading
import time
from typing import Any

from fieldrx_edge.cab.live import LiveState
from fieldrx_edge.cab.operator import OperatedMotor, Operator
from fieldrx_edge.jobkinds.registry import kind_of

HAND_ACTIONS = ("pause", "resume", "override", "section")


class ControlError(ValueError):
    """A button or value the session cannot take; the screen shows the message."""


class Control:
    def __init__(
        self, live: LiveState, operator: Operator, session: Any, store: Any, opts: Any
    ) -> None:
        self.live = live
        self.operator = operator
        self.session = session
        self.store = store
        self.opts = opts
        self.server: Any = None
        self.started = threading.Event()
        self.closed = threading.Event()
        self.summary: dict[str, Any] | None = None

    # -- wiring ------------------------------------------------------------

    def bind_agent(self, agent: Any) -> None:
        """``run``: the operator stands between the runtime's target and the meter."""
        agent.motor = OperatedMotor(agent.motor, self.operator)

    def wait_for_start(self) -> None:
        self.live.state = "ready"
        self.started.wait()

    def uploading(self) -> None:
        self.live.state = "uploading"
        with self.live.lock:
            self.live.changed.notify_all()

    def finish(self) -> None:
        """The job ended (path driven, source ended, or Finish): summary on the screen,
        served ``linger_s`` more seconds or until the screen's Close."""
        snap = self.live.snapshot()
        self.summary = {
            "records": self.live.n,
            "cells_covered": snap["cells_covered"],
            "area_done_ha": snap["area"]["done_ha"],
            "area_left_ha": snap["area"]["left_ha"],
            "applied_kg": snap["product"]["applied_kg"],
            "alarms": [a["name"] for a in snap["alarms"]],
            "uplink": snap["uplink"],
        }
        self.live.state = "finished"
        self.live.summary = self.summary
        with self.live.lock:
            self.live.changed.notify_all()
        if self.opts.linger_s > 0:
            self.closed.wait(self.opts.linger_s)
        if self.server is not None:
            self.server.close()

    # -- the screen --------------------------------------------------------

    def jobs(self) -> list[dict[str, Any]]:
        """Cached jobs (the state dir's) plus the one in the session."""
        job = self.session.job
        out = [_job_row(job, self.live.state)]
        if self.store is not None:
            for jid in self.store.job_ids():
                if jid == job.job_id:
                    continue
                try:
                    other = self.store.load(jid)
                except Exception as e:  # a damaged package is listed as such, not hidden
                    out.append({"job_id": jid, "error": str(e)})
                    continue
                state = self.store.load_progress(jid).get("state", "downloaded")
                out.append(_job_row(other, state))
        return out

    def act(self, body: dict[str, Any]) -> dict[str, Any]:
        action = body.get("action")
        op = self.operator
        kind = self.session.job.kind
        if action in HAND_ACTIONS and not kind_of(kind).hand_overrides:
            # the sensor kinds' loops take no operator hand yet: a tag on their records
            # would claim an override the meter never made
            raise ControlError(f"{action}: not available on a {kind} job")
        if action == "start":
            self.started.set()
            self.live.state = "running"
        elif action == "pause":
            op.set_paused(True)
            self.live.state = "paused"
        elif action == "resume":
            op.set_paused(False)
            self.live.state = "running"
        elif action == "finish":
            self.session.finish_requested.set()
        elif action == "close":
            self.closed.set()
        elif action == "override":
            op.nudge(_int(body, "steps", -10, 10))
        elif action == "section":
            op.toggle_section(_int(body, "section", 0, 63))
        elif action == "ack":
            return {"acknowledged": self.live.acknowledge(), "operator": op.to_dict()}
        elif action == "pull":
            return {"pulled": self.pull()}
        elif action == "tank":
            kg = body.get("kg")
            if not isinstance(kg, int | float) or isinstance(kg, bool) or not 0 < kg <= 100_000:
                raise ControlError(f"tank: kg must be a number in (0, 100000], got {kg!r}")
            self.live.tank_kg = float(kg)
        else:
            raise ControlError(
                f"unknown action {action!r}: start, pause, resume, finish, close, override,"
                " section, ack, tank, pull"
            )
        with self.live.lock:
            self.live.changed.notify_all()
        return {"ok": True, "operator": op.to_dict(), "state": self.live.state, "t": time.time()}

    def pull(self) -> dict[str, Any]:
        """New jobs from the server into the state dir (``jobs.pull``), when online."""
        from fieldrx_edge.jobs import pull

        o = self.session.opts
        if self.store is None or not (o.server and o.token) or o.offline:
            raise ControlError("pull: no server configured for this tractor (pull --server)")
        return dict(pull(self.store, o.server, o.token))


def _int(body: dict[str, Any], key: str, lo: int, hi: int) -> int:
    v = body.get(key)
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        raise ControlError(f"{key} must be an integer in {lo}..{hi}, got {v!r}")
    return v


def _job_row(job: Any, state: str) -> dict[str, Any]:
    """One line of the jobs list: what the job is and whether this machine can run it."""
    from fieldrx_edge.cab.geometry import JobGeometry

    geo = JobGeometry(job)
    planned = sum(
        r * a / 1e4 for r, a in zip(job.rate_kg_ha, geo.areas, strict=True) if r > 0
    )  # kg: rate (kg/ha) x cell area
    check = "ok"
    try:
        job.validate()
    except Exception as e:  # the package's own check (checksum, shapes, settings)
        check = f"failed: {e}"
    return {
        "job_id": job.job_id,
        "kind": job.kind,
        "field": job.field_name,
        "product": job.product,
        "prescription_version": job.prescription_version,
        "planned_kg": round(planned, 1) if kind_of(job.kind).rates_from == "cells" else None,
        "area_ha": round(geo.total_area / 1e4, 3),
        "machine_check": check,
        "state": state,
    }
