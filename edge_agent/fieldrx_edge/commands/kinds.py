"""``fieldrx-edge simulate`` and ``fieldrx-edge run`` for the sensor job kinds.

``simulate``: drives the kind's simulator over the job's field; with ``--server`` the
records go through the durable queue and the HTTP uplink exactly as ``run``'s, and the job
is reported running, then completed. The last stdout line is the simulator's own figures
(JSON), which the server's report must reproduce.

``run``: the tractor. GNSS from ``--source`` (speed, position; a thread), the kind's sensor
from ``--sensor`` (``serial:/dev/ttyUSB1@38400`` or ``file:log``, see ``sensors``); one
record per sensor line. The sensor clock is the line's own time when it has one, else one
sample period after the previous line (a rejected line has no trustworthy time). A rejected
line holds the last good value for the job's ``sensor_hold_s`` (alarm ``sensor_fault``),
then the output stops (alarm ``sensor_lost``: shaft target 0 / cylinder command 0, held
still) until good lines return.
A sensor that falls silent is noticed on the wall clock: with no line for two sample periods
the loop ticks on its own (reason ``silent``), the sensor clock advancing by the time that
passed, so a dead serial link holds, then stops, like bad lines do. Not yet: hardware
drivers for the shaft motor and the cylinder of these kinds (both are the papers' models
here, as ``--motor sim``).
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from typing import Any

from fieldrx_edge.job_package import JobPackage


def simulate_kind(a: argparse.Namespace, job: JobPackage) -> int:
    from fieldrx_edge.commands.sessions import finished_early, session_report, sim_session
    from fieldrx_edge.jobkinds.seeding import simulate_seeding
    from fieldrx_edge.jobkinds.topdress import simulate_topdress
    from fieldrx_edge.session import JobFinished

    session = sim_session(a, job)
    sink = session.put_many if (a.server or session.cab is not None) else None
    session.start(report=True)
    ctl = None
    if a.controller:
        from fieldrx_edge.jobkinds.settings import validate_settings

        ctl = validate_settings(job.kind, {"controller": {"name": a.controller}})["controller"]
    fault = tuple(a.sensor_fault) if getattr(a, "sensor_fault", None) else None
    drive = simulate_topdress if job.kind == "ndvi_topdress" else simulate_seeding
    try:
        out = drive(
            job, seed=a.seed, sink=sink, controller=ctl, fault_at_s=fault, realtime=a.realtime
        )
    except JobFinished:
        return finished_early(a, session)
    session_report(session, out)
    print(json.dumps(out), flush=True)
    if session.cab is not None:
        session.cab.finish()  # the summary on the screen, after the figures are out
    return 0


SILENT = None  # what ``sensor_lines`` yields when the sensor said nothing for two periods


def sensor_lines(source: Any, period_s: float) -> Any:
    """Lines of a sensor source (read in a thread), or ``SILENT`` every two sample periods
    without a line; ends when the source ends. Empty lines (a TCP read timeout) are silence."""
    import queue as queue_mod

    q: queue_mod.Queue[Any] = queue_mod.Queue(maxsize=10_000)
    end = object()

    def reader() -> None:
        try:
            for ln in source:
                if ln:
                    q.put(ln)
        finally:
            q.put(end)

    threading.Thread(target=reader, daemon=True).start()
    while True:
        try:
            item = q.get(timeout=2.0 * period_s)
        except queue_mod.Empty:
            yield SILENT
            continue
        if item is end:
            return
        yield item


def run_kind(a: argparse.Namespace, job: JobPackage, store: Any) -> int:
    """The agent's loop for a sensor kind (see the module doc), in the job's session."""
    from fieldrx_edge.commands.sessions import open_session
    from fieldrx_edge.gnss.sources import open_source
    from fieldrx_edge.jobkinds.sensors import SensorError, parse_ndvi
    from fieldrx_edge.ndvi import GnssSpeed
    from fieldrx_edge.protocol import TelemetryRecord

    if not a.sensor:
        raise SystemExit(f"a {job.kind} job needs --sensor (serial:DEV@BAUD or file:PATH)")
    queue = open_session(a, job, store, "full")
    queue.start(report=False)
    gnss = GnssSpeed(open_source(a.source, a.replay_speed or None))
    speed = a.replay_speed if a.replay_speed > 0 else None
    n = 0
    errors: dict[str, int] = {}
    from fieldrx_edge.gnss.utm import UtmProjection
    from fieldrx_edge.locate import locator_for_job

    proj = UtmProjection(job.utm_epsg)
    loc, _ = locator_for_job(job)

    def where() -> tuple[tuple[float, float] | None, int | None]:
        """(UTM position, plan cell seq) of the latest fix; None without a fix."""
        if gnss.lon is None or gnss.lat is None:
            return None, None
        xy = proj.forward(gnss.lon, gnss.lat)
        k = loc.locate(*xy)
        return xy, (int(job.seq[k]) if k >= 0 else None)

    if job.kind == "ndvi_topdress":
        from fieldrx_edge.jobkinds.topdress import PLANT_DT, TopdressLoop, build_shaft_controller
        from fieldrx_edge.metering import rate_for_shaft_rpm
        from fieldrx_edge.plants import seed000_shaft

        loop = TopdressLoop(job)
        ctl = job.kind_settings["controller"]
        shaft_ctrl, fscale = build_shaft_controller(ctl)
        shaft = seed000_shaft(PLANT_DT)  # --motor sim: seed 000's shaft chain
        ratio = max(1, round(float(ctl["period_s"]) / PLANT_DT))
        u = y = 0.0
        n_s = int(job.kind_settings["sensors"]["count"])
        period = 1.0 / float(job.kind_settings["sensors"]["sample_hz"])
        now = 0.0
        mono = time.monotonic()
        for line in sensor_lines(open_source(a.sensor, speed), period):
            vals = None
            wall, mono = time.monotonic() - mono, time.monotonic()
            if line is SILENT:  # the clock moves by the time that passed without a line
                now += wall
                loop.guard.bad("silent")
                errors["silent"] = errors.get("silent", 0) + 1
            else:
                now += period
                try:
                    tl, vals = parse_ndvi(line, n_s)
                    now = tl if tl is not None else now
                except SensorError as exc:
                    loop.guard.bad(exc.reason)
                    errors[exc.reason] = errors.get(exc.reason, 0) + 1
            v = gnss.speed_m_s or 0.0
            xy, cell = where()
            inside = True
            if loop.boundary is not None:  # no fix: no position to keep inside the field
                inside = xy is not None and loop.boundary.contains(*xy)
            d = loop.on_sample(now, vals, v, inside)
            for k in range(max(1, round(period / PLANT_DT))):  # the shaft until the next line
                if k % ratio == 0:
                    u = shaft_ctrl.step(d.target_rpm * fscale, y * fscale, float(ctl["period_s"]))
                    if d.target_rpm <= 0.0:
                        u = 0.0
                        shaft_ctrl.reset()
                y = max(0.0, shaft.step(u))
            applied = rate_for_shaft_rpm(loop.cal, y, loop.width_m, v) if v > 0.05 else 0.0
            rec = TelemetryRecord(
                machine_id=job.machine_id, seq=1, t=time.time(), lon=gnss.lon, lat=gnss.lat,
                fix_quality=gnss.fix_quality, speed_filtered_m_s=v, job_id=job.job_id,
                cell_seq=cell, target_rate_kg_ha=d.rate_kg_ha, target_shaft_rpm=d.target_rpm,
                actual_shaft_rpm=y, applied_rate_kg_ha=applied if d.target_rpm > 0 else 0.0,
                duty=100.0 * u / 5.0, ndvi=d.ndvi, ndvi_raw=d.ndvi_raw, implement_down=True,
                alarms=sorted(set(d.alarms)),
            )  # fmt: skip
            queue.put(rec.to_dict())
            n += 1
    else:
        from fieldrx_edge.jobkinds.seeding import DepthJobLoop, build_depth_controller
        from fieldrx_edge.plants import seed002_depth

        dl = DepthJobLoop(job)
        ks = job.kind_settings
        ctrl = build_depth_controller(ks["controller"], float(ks["actuator_speed_mm_s"]))
        period = 0.1  # one command per sensor line here (the 1 ms loop belongs to the drive)
        cylinder = seed002_depth(period)  # --motor sim: the adjusting mechanism's model
        now = 0.0
        mono = time.monotonic()
        for line in sensor_lines(open_source(a.sensor, speed), period):
            wall, mono = time.monotonic() - mono, time.monotonic()
            if line is SILENT:
                now += wall
                dl.guard.bad("silent")
            else:
                now = dl.on_line(now + period, line)
            depth, alarms = dl.depth(now)
            # sensor lost: command 0, the cylinder holds where it is (seed 002's mechanism
            # integrates the command); held value: the loop goes on with it
            u = 0.0 if depth is None else ctrl.step(dl.target_mm, depth, period)
            pos = cylinder.step(u)
            gains = getattr(ctrl, "gains", (ctrl.kp, ctrl.ki, ctrl.kd))
            rec = TelemetryRecord(
                machine_id=job.machine_id, seq=1, t=time.time(), lon=gnss.lon, lat=gnss.lat,
                fix_quality=gnss.fix_quality, speed_filtered_m_s=gnss.speed_m_s,
                job_id=job.job_id, cell_seq=where()[1], depth_mm=depth, implement_down=True,
                alarms=sorted(set(alarms)),
                duty=u, actuator_mm=pos, gain_kp=float(gains[0]), gain_ki=float(gains[1]),
                gain_kd=float(gains[2]),
            )  # fmt: skip
            queue.put(rec.to_dict())
            n += 1
        errors = dict(dl.guard.errors)
    drained = queue.close()["drained"]
    print(json.dumps({"job_id": job.job_id, "kind": job.kind, "records": n,
                      "sensor_errors": errors, "drained": drained}), flush=True)  # fmt: skip
    if queue.cab is not None:
        queue.cab.finish()
    return 0
