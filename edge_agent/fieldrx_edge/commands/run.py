"""``pull``, ``run`` (a cached job from a live GNSS source) and ``ecu`` (the rate ECU)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import threading
import time
from typing import Any

from fieldrx_edge.commands.sessions import open_session
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.jobkinds.registry import kind_of
from fieldrx_edge.jobs import JobStore, pull
from fieldrx_edge.rateunits.registry import RateUnitError
from fieldrx_edge.session import JobSession, UplinkOptions, load_job

log = logging.getLogger("fieldrx_edge")


def cmd_pull(a: argparse.Namespace) -> int:
    store = JobStore(a.state_dir)
    cfg = store.config()
    server = a.server or cfg.get("server")
    token = a.token or cfg.get("token")
    if not server or not token:
        raise SystemExit("pull needs --server and --token (saved for later runs)")
    if getattr(a, "uplink", None):
        store.set_config(uplink=a.uplink)  # the profile of the jobs this machine starts
    out = pull(store, server, token)
    print(json.dumps(out))
    return 1 if out["failed"] else 0


def uplink_profile(a: argparse.Namespace, store: JobStore, progress: dict[str, Any]) -> str:
    """The job's uplink profile: fixed when the job first runs (its report is built from one
    kind of records), else --uplink, else the saved config's "uplink", else full."""
    from fieldrx_edge.uplink.thin import check_profile

    asked = check_profile(getattr(a, "uplink", None) or store.config().get("uplink") or "full")
    kept = progress.get("uplink")
    if kept and kept != asked:
        log.warning("job keeps uplink profile %s (it started with it), not %s", kept, asked)
        return str(kept)
    return asked


def _motor(a: argparse.Namespace, job: JobPackage, settings: Any, period: float) -> Any:
    from fieldrx_edge.motor import MotorLoop, SerialMotorDriver, build_controller, simulated_motor

    if a.implement == "isobus":
        return isobus_implement(a, job)
    if a.motor == "sim":
        driver: Any = simulated_motor(period)
    else:
        driver = SerialMotorDriver(a.motor.removeprefix("serial:"))
    return MotorLoop(build_controller(settings), driver, period)


def _runtime_config(a: argparse.Namespace, settings: Any, period: float) -> Any:
    from fieldrx_edge.motor import closed_loop_t50_s
    from fieldrx_edge.runtime import RuntimeConfig

    # motor response added to the look-ahead: measured on the seed 001 motor model
    # with the job's controller unless given (real hardware: measure and pass it)
    t50 = a.response_s if a.response_s is not None else closed_loop_t50_s(settings, period)
    t50_stop = closed_loop_t50_s(settings, period, 100.0, 0.0)
    t50_start = closed_loop_t50_s(settings, period, 0.0, 100.0)
    return RuntimeConfig(
        lag_compensation=a.lag_compensation,
        response_s=t50,
        stop_extra_s=max(0.0, t50_stop - t50),
        # spin-up anticipation is off: at a field edge it would put fertilizer outside
        start_extra_s=max(0.0, t50_start - t50) if a.early_start else 0.0,
        min_fix_quality=a.min_fix_quality,
        max_hdop=a.max_hdop if a.max_hdop > 0 else None,
    )


def _feed(agent: Any, lines: Any, session: JobSession, state: dict[str, int], save: Any) -> None:
    """GNSS lines into the runtime until the source ends or the cab's Finish; a replayed
    file resumes after the ``state["lines"]`` a killed run got through."""
    done = state["lines"]
    for i, line in enumerate(lines):
        if i < done:
            continue  # a replayed file resumes where the killed run stopped
        if session.finish_requested.is_set():
            break
        agent.handle_line(line)
        state["lines"] = i + 1
        if state["lines"] % 50 == 0:
            save()


def cmd_run(a: argparse.Namespace) -> int:
    from fieldrx_edge.gnss.sources import open_source
    from fieldrx_edge.runtime import Agent

    store = JobStore(a.state_dir)
    job = load_job(a.job, store)
    if not (store.root / "jobs" / f"{job.job_id}.json").exists():
        store.save_package(job.to_json())
    own = kind_of(job.kind).run(a, job, store)  # a kind with its own loop (sensor kinds)
    if own is not None:
        return own
    if a.implement != "isobus":  # the TC converts for an ISOBUS implement itself
        job = motor_job(job)
    progress = store.load_progress(job.job_id)
    settings = job.controller
    if a.controller:
        settings = dataclasses.replace(settings, name=a.controller, params={})
    period = settings.period_s or 0.01
    motor = _motor(a, job, settings, period)
    lines_done = int(progress.get("source_lines", 0)) if a.source.startswith("file:") else 0
    state = {"lines": lines_done}

    def save_progress(finished: list[int] | None = None) -> None:
        if finished is not None:
            progress["finished"] = sorted(set(finished))
        progress["source_lines"] = state["lines"]
        if progress.get("state") != "completed":
            progress["state"] = "running"
        store.save_progress(job.job_id, progress)

    profile = uplink_profile(a, store, progress)
    progress["uplink"] = profile
    session = open_session(a, job, store, profile)
    agent = Agent(
        job, session, motor, _runtime_config(a, settings, period),
        progress.get("finished", []), save_progress,
    )  # fmt: skip
    if session.cab is not None:
        session.cab.bind_agent(agent)
    session.start(report=not a.offline, wait=False)
    motor_stop = threading.Event()
    mth = threading.Thread(target=motor.run, args=(motor_stop,), daemon=True)
    mth.start()
    speed = a.replay_speed if a.replay_speed > 0 else None
    t0 = time.monotonic()
    try:
        _feed(agent, open_source(a.source, speed), session, state, save_progress)
    except KeyboardInterrupt:
        pass
    finally:
        motor_stop.set()
        mth.join(timeout=2.0)
    done = len(set(progress.get("finished", []))) >= job.n_cells
    if done:
        progress["state"] = "completed"
    save_progress()
    up = session.close(completed=done, report=not a.offline)
    out = {
        "job_id": job.job_id,
        "implement": a.implement,
        "records": agent.records,
        "finished_cells": len(progress.get("finished", [])),
        "queue": up["queue"],
        "uplink": up["uplink"],
        "drained": up["drained"],
        "parse": agent.parser.stats.to_dict(),
        "wall_s": round(time.monotonic() - t0, 2),
    }
    if a.implement == "isobus":
        out["isobus"] = isobus_stats(motor.tc)
        motor.tc.node.close()
    print(json.dumps(out), flush=True)
    if session.cab is not None:
        session.cab.finish()
    return 0


# -- ISOBUS -------------------------------------------------------------------


def open_can(a: argparse.Namespace) -> Any:
    """The ``--can`` bus, or a clear exit naming the option and what failed."""
    from fieldrx_edge.isobus.transport import CanSpecError, open_bus

    try:
        return open_bus(a.can, a.can_bitrate)
    except CanSpecError as e:
        raise SystemExit(str(e)) from None
    except Exception as e:  # python-can: no such interface, driver or device
        raise SystemExit(f"--can {a.can}: cannot open the CAN interface: {e}") from None


def isobus_implement(a: argparse.Namespace, job: JobPackage) -> Any:
    """The TC server on ``--can`` standing where the motor loop stands."""
    from fieldrx_edge.isobus.implement import IsobusImplement
    from fieldrx_edge.isobus.network import Node
    from fieldrx_edge.isobus.pair import tc_name
    from fieldrx_edge.isobus.tc_server import TaskControllerServer

    if not a.can:
        raise SystemExit("--implement isobus needs --can INTERFACE:CHANNEL (e.g. socketcan:can0)")
    units = job_rate_units(job, a.density)
    node = Node(open_can(a), tc_name(), a.tc_address, label="tc")
    tc = TaskControllerServer(node, implement_width_m=job.implement_width_m, units=units)
    return IsobusImplement(tc)


def motor_job(job: JobPackage) -> JobPackage:
    """The meter's calibration is in g per revolution: a job in another unit is metered by
    mass through its product lot (l/ha x density, ...), and refused when the lot does not
    say rather than metered as if its litres were kilograms."""
    try:
        return job.in_mass()
    except RateUnitError as e:
        unit = job.unit()
        raise SystemExit(
            f"job {job.job_id} is in {unit.name}: the meter's calibration is in g per"
            f" revolution and {e}; run it with --implement isobus on a {unit.quantity}-rate"
            " implement"
        ) from None


def job_rate_units(job: JobPackage, density_kg_l: float | None = None) -> Any:
    """The job's rate unit and its product's density, from the package (the product
    carries its density); ``--density`` only fills in for a package without one, and a
    different value is refused rather than silently overriding the product's."""
    from fieldrx_edge.isobus.tc_mapping import RateUnits

    d = job.product_density_kg_l or None
    if density_kg_l is not None and d is not None and abs(density_kg_l - d) > 1e-9:
        raise SystemExit(
            f"--density {density_kg_l} kg/l contradicts the job package's product density "
            f"{d} kg/l ({job.product or 'product'}): leave --density out"
        )
    try:
        return RateUnits(job.rate_unit, d if d is not None else density_kg_l, job.unit_lot)
    except ValueError as e:
        raise SystemExit(f"job {job.job_id}: {e}") from None


def isobus_stats(tc: Any) -> dict[str, Any]:
    c = tc.client
    return {
        "address": tc.node.address,
        "client": None
        if c is None
        else {
            "address": c.address,
            "kind": c.kind,
            "sections": c.n_sections,
            "actual_rate_kg_ha": c.actual_rate_kg_ha,
            "actual_rpm": c.actual_rpm,
        },
        "alarms": tc.alarm_list(),
        "setpoints_sent": tc.setpoints_sent,
        "values_rx": tc.values_rx,
        "bus": tc.node.stats.to_dict(),
    }


def ecu_session(a: argparse.Namespace, job: JobPackage) -> JobSession:
    """The ECU's session for ``--job``: the same ``JobSession`` as ``run``'s, its queue in
    --state-dir (else a temporary dir), sending only when an uplink is configured. The ECU
    puts no records (the task controller's side logs the drive) and reports no job state:
    the TC side owns the job's state; the session gives the ECU the job and its stop."""
    store = JobStore(a.state_dir) if a.state_dir else None
    opts = UplinkOptions.from_args(a, store)
    return JobSession(job, opts, store.queue_path() if store is not None else None)


def _ecu_config(a: argparse.Namespace) -> tuple[Any, float, Any, JobSession | None]:
    """Calibration, width, controller settings and session: the job's with ``--job``."""
    from fieldrx_edge.job_package import ControllerSettings
    from fieldrx_edge.metering import LinearCalibration, calibration_from_dict

    session = None
    if a.job:
        job = load_job(a.job, JobStore(a.state_dir))
        session = ecu_session(a, job)
        cal: Any = calibration_from_dict(job.calibration)
        width = a.width or job.implement_width_m
        settings = job.controller
    else:
        cal, width = LinearCalibration(), a.width or 2.3
        settings = ControllerSettings(name="ladrc")
    if a.controller:
        settings = dataclasses.replace(settings, name=a.controller, params={})
    return cal, width, settings, session


def cmd_ecu(a: argparse.Namespace) -> int:
    """The rate ECU: the motor loop as an ISOBUS TC client, until Ctrl-C or --duration."""
    from fieldrx_edge.isobus.network import Node
    from fieldrx_edge.isobus.pair import ecu_name
    from fieldrx_edge.isobus.rate_ecu import RateEcu, run_ecu
    from fieldrx_edge.motor import MotorLoop, SerialMotorDriver, build_controller, simulated_motor

    cal, width, settings, session = _ecu_config(a)
    period = settings.period_s or 0.01
    driver: Any = (
        simulated_motor(period)
        if a.motor == "sim"
        else SerialMotorDriver(a.motor.removeprefix("serial:"))
    )
    motor = MotorLoop(build_controller(settings), driver, period)
    node = Node(open_can(a), ecu_name(a.identity), a.address, label="ecu")
    ecu = RateEcu(node, cal, width, a.sections)
    # with a job, the session's Finish is the ECU's stop, as it is the drive's in `run`
    stop = session.finish_requested if session is not None else threading.Event()
    mstop = threading.Event()
    mth = threading.Thread(target=motor.run, args=(mstop,), daemon=True)
    mth.start()
    if a.duration > 0:
        threading.Timer(a.duration, stop.set).start()
    if session is not None:
        session.start(report=False)
    node.start()
    try:
        run_ecu(ecu, motor, stop, period)
    except KeyboardInterrupt:
        pass
    finally:
        mstop.set()
        mth.join(timeout=2.0)
        node.close()
    out: dict[str, Any] = {
        "address": node.address,
        "state": ecu.state,
        "tc_address": ecu.tc_addr,
        "pool_bytes": len(ecu.pool),
        "setpoints_rx": ecu.setpoints_rx,
        "rate_kg_ha": ecu.rate_kg_ha(),
        "sections": ecu.sections(),
        "alarms": sorted(ecu.alarms | node.alarms),
        "bus": node.stats.to_dict(),
    }
    if session is not None and session.job is not None:
        out["job_id"] = session.job.job_id
        out["uplink_state"] = session.uplink_state()
        out["drained"] = session.close(report=False)["drained"]
    print(json.dumps(out))
    return 0
