"""``fieldrx-edge``: pull jobs, run one, simulate one, replay a receiver log, NDVI mode.

    fieldrx-edge pull --server URL --token DEVICE_TOKEN [--state-dir D]
    fieldrx-edge run JOB_ID --source serial:/dev/ttyACM0@115200 [--motor serial:/dev/ttyUSB0]
    fieldrx-edge run JOB_ID --source file:drive.nmea --replay-speed 10 --offline
    fieldrx-edge run JOB_ID --source tcp:192.168.1.5:2101 --mqtt 127.0.0.1:1884
    fieldrx-edge simulate JOB.json|demo:35x23|demo:20ha --speed 3-9km/h --gnss-noise 0.02 \
        --controller ladrc --lag-compensation on [--seed N] [--server URL --token T] --json
    fieldrx-edge run JOB_ID --source ... --implement isobus --can socketcan:can0
    fieldrx-edge ecu --can pcan:PCAN_USBBUS1 [--job JOB_ID|FILE] [--motor serial:/dev/ttyUSB0]
    fieldrx-edge simulate demo:35x23 --implement isobus      (TC -> virtual CAN -> rate ECU)
    fieldrx-edge replay-nmea LOG [--json]
    fieldrx-edge ndvi file:ndvi.csv [--gnss SRC | --speed-kmh 6] [--machine-id N] [--json]

State (cached jobs, progress, telemetry queue) lives in --state-dir, default
$FIELDRX_EDGE_HOME or ~/.fieldrx-edge. After ``pull`` the agent needs no network.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import logging
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any

from fieldrx_edge.jobs import JobStore, pull, report_state
from fieldrx_edge.protocol import UPLINK_PROFILES, UPLOAD_PERIOD_S, JobPackage, mqtt_username
from fieldrx_edge.uplink.pacing import upload_period

log = logging.getLogger("fieldrx_edge")
UPLINK_HELP = (
    "telemetry profile: full (every fix) or thin (1 Hz track + one record per cell left; the"
    " 10 Hz log stays in the state dir, `upload-log` sends it). Default: the config's"
    ' "uplink" (set by `pull --uplink`), else full'
)

UPLOAD_PERIOD_HELP = (
    "seconds between uploads of a batch that is not full (a backlog is sent at once)."
    " Default: the uplink profile's, " + ", ".join(f"{k} {v:g}" for k, v in UPLOAD_PERIOD_S.items())
)


def _on_off(v: str) -> bool:
    if v.lower() in ("on", "true", "1", "yes"):
        return True
    if v.lower() in ("off", "false", "0", "no"):
        return False
    raise argparse.ArgumentTypeError("expected on or off")


def _speed_range(v: str) -> tuple[float, float]:
    """'3-9km/h', '3-9', '6km/h' -> (lo, hi) km/h."""
    s = v.lower().replace("km/h", "").replace("kmh", "").strip()
    lo, _, hi = s.partition("-")
    a = float(lo)
    b = float(hi) if hi else a
    if not 0 < a <= b:
        raise argparse.ArgumentTypeError(f"bad speed range {v!r}")
    return a, b


def _load_job(spec: str, store: JobStore | None = None) -> JobPackage:
    """A job from a file path, ``demo:35x23`` / ``demo:20ha``, or a cached job id."""
    if spec.startswith("demo:"):
        from fieldrx_edge.sim.fields import field_20ha, rect_job

        what = spec[5:]
        if what == "20ha":
            return field_20ha()
        length, _, width = what.partition("x")
        return rect_job(length_m=float(length), width_m=float(width))
    p = Path(spec)
    if p.exists():
        return JobPackage.from_json(p.read_bytes(), verify=True)
    if spec.isdigit() and store is not None:
        if int(spec) in store.job_ids():
            return store.load(int(spec))
        raise SystemExit(
            f"job {spec}: not cached in {store.root} (cached: {store.job_ids() or 'none'});"
            " run `fieldrx-edge pull` with the same --state-dir first"
        )
    raise SystemExit(f"job {spec!r}: no such file, demo: spec or cached job id")


# -- pull -----------------------------------------------------------------


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


# -- run ------------------------------------------------------------------


def _uplink_profile(a: argparse.Namespace, store: JobStore, progress: dict[str, Any]) -> str:
    """The job's uplink profile: fixed when the job first runs (its report is built from one
    kind of records), else --uplink, else the saved config's "uplink", else full."""
    from fieldrx_edge.uplink.thin import check_profile

    asked = check_profile(getattr(a, "uplink", None) or store.config().get("uplink") or "full")
    kept = progress.get("uplink")
    if kept and kept != asked:
        log.warning("job keeps uplink profile %s (it started with it), not %s", kept, asked)
        return str(kept)
    return asked


def _thin_uplink(job: JobPackage, root: Path, queue: Any) -> tuple[Any, Any]:
    """(ThinUplink the agent writes to, its cell queue) in state dir ``root``."""
    from fieldrx_edge.uplink import TelemetryQueue
    from fieldrx_edge.uplink.thin import ThinUplink, raw_log_path

    cells = TelemetryQueue(root / "cells.sqlite", job.machine_id, kind="cells")
    return ThinUplink(job, queue, cells, raw_log_path(root, job.job_id)), cells


def _make_sender(
    a: argparse.Namespace,
    store: JobStore,
    queue: Any,
    extra: tuple[Any, ...] = (),
    profile: str = "full",
) -> Any:
    cfg = store.config()
    period = upload_period(profile, getattr(a, "upload_period", None))
    server = a.server or cfg.get("server")
    token = a.token or cfg.get("token")
    if a.mqtt:
        from fieldrx_edge.uplink import MqttSender

        # the broker knows the machine as machine-<id>, its password is the device token
        if not token:
            raise SystemExit("--mqtt needs the device token (--token, or saved by pull)")
        host, _, port = a.mqtt.partition(":")
        ca = getattr(a, "mqtt_ca", None)
        return MqttSender(
            queue,
            host or "127.0.0.1",
            int(port or (8883 if ca else 1884)),
            username=mqtt_username(queue.machine_id),
            password=token,
            tls_ca=ca,
            extra_queues=extra,
            upload_period_s=period,
        )
    if server and token and not a.offline:
        from fieldrx_edge.uplink import HttpSender

        return HttpSender(queue, server, token, extra_queues=extra, upload_period_s=period)
    return None


def cmd_run(a: argparse.Namespace) -> int:
    from fieldrx_edge.gnss.sources import open_source
    from fieldrx_edge.motor import MotorLoop, SerialMotorDriver, build_controller, simulated_motor
    from fieldrx_edge.runtime import Agent, RuntimeConfig
    from fieldrx_edge.uplink import TelemetryQueue

    store = JobStore(a.state_dir)
    job = _load_job(a.job, store)
    if not (store.root / "jobs" / f"{job.job_id}.json").exists():
        store.save_package(job.to_json())
    if job.kind != "prescription_map":  # seed 000 / 002 jobs
        from fieldrx_edge.jobkinds.cli import run_kind

        return run_kind(a, job, store, _make_sender)
    progress = store.load_progress(job.job_id)
    queue = TelemetryQueue(store.queue_path(), job.machine_id)
    settings = job.controller
    if a.controller:
        settings = dataclasses.replace(settings, name=a.controller, params={})
    period = settings.period_s or 0.01
    motor: Any
    if a.implement == "isobus":
        motor = _isobus_implement(a, job)
    else:
        if a.motor == "sim":
            driver: Any = simulated_motor(period)
        else:
            driver = SerialMotorDriver(a.motor.removeprefix("serial:"))
        motor = MotorLoop(build_controller(settings), driver, period)
    lines_done = int(progress.get("source_lines", 0)) if a.source.startswith("file:") else 0
    state = {"lines": lines_done}

    def save_progress(finished: list[int] | None = None) -> None:
        if finished is not None:
            progress["finished"] = sorted(set(finished))
        progress["source_lines"] = state["lines"]
        if progress.get("state") != "completed":
            progress["state"] = "running"
        store.save_progress(job.job_id, progress)

    from fieldrx_edge.motor import closed_loop_t50_s

    # motor response added to the look-ahead: measured on the seed 001 motor model
    # with the job's controller unless given (real hardware: measure and pass it)
    t50 = a.response_s if a.response_s is not None else closed_loop_t50_s(settings, period)
    t50_stop = closed_loop_t50_s(settings, period, 100.0, 0.0)
    t50_start = closed_loop_t50_s(settings, period, 0.0, 100.0)
    rcfg = RuntimeConfig(
        lag_compensation=a.lag_compensation,
        response_s=t50,
        stop_extra_s=max(0.0, t50_stop - t50),
        # spin-up anticipation is off: at a field edge it would put fertilizer outside
        start_extra_s=max(0.0, t50_start - t50) if a.early_start else 0.0,
        min_fix_quality=a.min_fix_quality,
        max_hdop=a.max_hdop if a.max_hdop > 0 else None,
    )
    profile = _uplink_profile(a, store, progress)
    progress["uplink"] = profile
    sink: Any = queue
    extra: tuple[Any, ...] = ()
    if profile == "thin":  # 1 Hz track + one record per cell; the 10 Hz log stays here
        sink, cells = _thin_uplink(job, store.root, queue)
        extra = (cells,)
    agent = Agent(job, sink, motor, rcfg, progress.get("finished", []), save_progress)
    sender = _make_sender(a, store, queue, extra, profile)
    stop = threading.Event()
    th = None
    if sender is not None:
        th = threading.Thread(target=sender.run, args=(stop,), daemon=True)
        th.start()
    motor_stop = threading.Event()
    mth = threading.Thread(target=motor.run, args=(motor_stop,), daemon=True)
    mth.start()
    speed = a.replay_speed if a.replay_speed > 0 else None
    if not a.offline:
        threading.Thread(
            target=report_state, args=(store, job.job_id, "running"), daemon=True
        ).start()
    t0 = time.monotonic()
    try:
        for i, line in enumerate(open_source(a.source, speed)):
            if i < lines_done:
                continue  # a replayed file resumes where the killed run stopped
            agent.handle_line(line)
            state["lines"] = i + 1
            if state["lines"] % 50 == 0:
                save_progress()
    except KeyboardInterrupt:
        pass
    finally:
        motor_stop.set()
        mth.join(timeout=2.0)
    done = len(set(progress.get("finished", []))) >= job.n_cells
    if profile == "thin":
        sink.flush()  # the cells of this run's last seconds, before the job can end
    if done:
        progress["state"] = "completed"
    save_progress()
    if done and not a.offline:
        report_state(store, job.job_id, "completed")
    drained = True
    if sender is not None:
        stop.set()
        if th is not None:
            th.join(timeout=5.0)
        drained = sender.drain(a.drain_timeout)
        sender.close()
    out = {
        "job_id": job.job_id,
        "implement": a.implement,
        "records": agent.records,
        "finished_cells": len(progress.get("finished", [])),
        "queue": queue.stats(),
        "uplink": sink.stats() if profile == "thin" else {"profile": "full"},
        "drained": drained,
        "parse": agent.parser.stats.to_dict(),
        "wall_s": round(time.monotonic() - t0, 2),
    }
    if a.implement == "isobus":
        out["isobus"] = _isobus_stats(motor.tc)
        motor.tc.node.close()
    print(json.dumps(out))
    return 0


# -- ISOBUS -------------------------------------------------------------------


def _address(v: str) -> int:
    """A source address, decimal or 0x.., 0..253 (254 and 255 are NULL and global)."""
    try:
        n = int(v, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad address {v!r}") from None
    if not 0 <= n <= 253:
        raise argparse.ArgumentTypeError(f"address {v!r} outside 0..253")
    return n


def _open_can(a: argparse.Namespace) -> Any:
    """The ``--can`` bus, or a clear exit naming the option and what failed."""
    from fieldrx_edge.isobus.transport import CanSpecError, open_bus

    try:
        return open_bus(a.can, a.can_bitrate)
    except CanSpecError as e:
        raise SystemExit(str(e)) from None
    except Exception as e:  # python-can: no such interface, driver or device
        raise SystemExit(f"--can {a.can}: cannot open the CAN interface: {e}") from None


def _isobus_implement(a: argparse.Namespace, job: JobPackage) -> Any:
    """The TC server on ``--can`` standing where the motor loop stands."""
    from fieldrx_edge.isobus.network import Node
    from fieldrx_edge.isobus.pair import tc_name
    from fieldrx_edge.isobus.tc_server import IsobusImplement, TaskControllerServer

    if not a.can:
        raise SystemExit("--implement isobus needs --can INTERFACE:CHANNEL (e.g. socketcan:can0)")
    node = Node(_open_can(a), tc_name(), a.tc_address, label="tc")
    tc = TaskControllerServer(node, implement_width_m=job.implement_width_m, density_kg_l=a.density)
    return IsobusImplement(tc)


def _isobus_stats(tc: Any) -> dict[str, Any]:
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


def cmd_ecu(a: argparse.Namespace) -> int:
    """The rate ECU: the motor loop as an ISOBUS TC client, until Ctrl-C or --duration."""
    from fieldrx_edge.isobus.network import Node
    from fieldrx_edge.isobus.pair import ecu_name
    from fieldrx_edge.isobus.rate_ecu import RateEcu, run_ecu
    from fieldrx_edge.metering import LinearCalibration, calibration_from_dict
    from fieldrx_edge.motor import MotorLoop, SerialMotorDriver, build_controller, simulated_motor
    from fieldrx_edge.protocol import ControllerSettings

    if a.job:
        job = _load_job(a.job, JobStore(a.state_dir))
        cal: Any = calibration_from_dict(job.calibration)
        width = a.width or job.implement_width_m
        settings = job.controller
    else:
        cal, width = LinearCalibration(), a.width or 2.3
        settings = ControllerSettings(name="ladrc")
    if a.controller:
        settings = dataclasses.replace(settings, name=a.controller, params={})
    period = settings.period_s or 0.01
    driver: Any = (
        simulated_motor(period)
        if a.motor == "sim"
        else SerialMotorDriver(a.motor.removeprefix("serial:"))
    )
    motor = MotorLoop(build_controller(settings), driver, period)
    node = Node(_open_can(a), ecu_name(a.identity), a.address, label="ecu")
    ecu = RateEcu(node, cal, width, a.sections)
    stop = threading.Event()
    mstop = threading.Event()
    mth = threading.Thread(target=motor.run, args=(mstop,), daemon=True)
    mth.start()
    if a.duration > 0:
        threading.Timer(a.duration, stop.set).start()
    node.start()
    try:
        run_ecu(ecu, motor, stop, period)
    except KeyboardInterrupt:
        pass
    finally:
        mstop.set()
        mth.join(timeout=2.0)
        node.close()
    out = {
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
    print(json.dumps(out))
    return 0


# -- simulate ---------------------------------------------------------------


def cmd_simulate(a: argparse.Namespace) -> int:
    import numpy as np

    from fieldrx_edge.sim.simulator import SimConfig, simulate, summary

    # a cached job id works as with `run` (pulled into --state-dir or the default one)
    job = _load_job(a.job, JobStore(a.state_dir) if a.job.isdigit() else None)
    if job.kind != "prescription_map":  # seed 000 / 002 jobs
        from fieldrx_edge.jobkinds.cli import simulate_kind

        return simulate_kind(a, job)
    lo, hi = a.speed
    cfg = SimConfig(
        speed_min_kmh=lo,
        speed_max_kmh=hi,
        gnss_noise_m=a.gnss_noise,
        speed_noise_m_s=a.speed_noise,
        controller=a.controller,
        lag_compensation=a.lag_compensation,
        seed=a.seed,
        gnss_hz=a.gnss_hz,
        realtime=a.realtime,
    )
    pair = None
    if a.implement == "isobus":
        from fieldrx_edge.isobus.pair import IsobusPair

        pair = IsobusPair(job, sections=a.sections)
        pair.connect()
        cfg = dataclasses.replace(cfg, implement=pair)
    sink = None
    sender = queue = thin = None
    if a.server:
        import tempfile

        from fieldrx_edge.uplink import HttpSender, TelemetryQueue

        if not a.token:
            raise SystemExit("--server needs --token")
        qdir = Path(a.state_dir) if a.state_dir else Path(tempfile.mkdtemp(prefix="fieldrx-sim-"))
        queue = TelemetryQueue(qdir / "queue.sqlite", job.machine_id)
        extra: tuple[Any, ...] = ()
        sink = queue.put_many
        if a.uplink == "thin":  # 1 Hz track + one record per cell (the agent's thin profile)
            thin, cells = _thin_uplink(job, qdir, queue)
            extra = (cells,)
            sink = thin.put_many
        sender = HttpSender(
            queue, a.server, a.token, extra_queues=extra,
            upload_period_s=upload_period(a.uplink, a.upload_period),
        )  # fmt: skip
    stop = threading.Event()
    sth = None
    if sender is not None:  # sends while the tractor drives, exactly like `run`
        sth = threading.Thread(target=sender.run, args=(stop,), daemon=True)
        sth.start()
    if a.server:
        from fieldrx_edge.jobs import post_state

        post_state(a.server, a.token, job.job_id, "running")
    res = simulate(job, cfg, sink=sink)
    if thin is not None:
        thin.flush()
    stop.set()
    if sth is not None:
        sth.join(timeout=15.0)
    res_u = None
    if a.lag_compensation:
        res_u = simulate(
            job,
            dataclasses.replace(cfg, lag_compensation=False, implement=None),
            max_runs=a.compare_runs,
        )
    out = summary(res, res_u if res_u is not None else res, cfg, job)
    out["uncompensated_runs"] = a.compare_runs if res_u is not None else "all"
    out["implement"] = a.implement
    if pair is not None:
        out["isobus"] = _isobus_stats(pair.tc)
        pair.close()
    if res_u is None:
        out["uncompensated_borders"] = out["lag_borders"]
    if sender is not None and queue is not None:
        out["telemetry_drained"] = sender.drain(a.drain_timeout)
        out["telemetry"] = queue.stats()
        out["uplink"] = thin.stats() if thin is not None else {"profile": "full"}
        sender.close()
        from fieldrx_edge.jobs import post_state

        # the simulated tractor drove the whole path: the job is done
        out["job_state_reported"] = post_state(a.server, a.token, job.job_id, "completed")
    seqs = res.extra["seq"]
    if a.cells_out:
        with open(a.cells_out, "w", newline="") as fh:
            w = csv.writer(fh)
            # m2/accuracy: what physically landed (the simulated truth); logged_*: the
            # as-applied kernel over the records the agent sent (the server's report)
            w.writerow(
                ["seq", "rate_kg_ha", "m1_g", "m2_g", "accuracy_pct", "logged_m2_g",
                 "logged_accuracy_pct"]
            )  # fmt: skip
            for s, r, m1, m2, acc, lm2, lacc in zip(
                seqs,
                res.extra["rate"],
                res.cell_m1_g,
                res.cell_m2_g,
                res.cell_accuracy_pct,
                res.extra["logged_m2_g"],
                res.extra["logged_accuracy_pct"],
                strict=True,
            ):
                w.writerow(
                    [
                        int(s),
                        float(r),
                        round(float(m1), 4),
                        round(float(m2), 4),
                        round(float(acc), 4),
                        round(float(lm2), 4),
                        round(float(lacc), 4),
                    ]
                )
    if not a.json or a.verbose:
        acc = res.cell_accuracy_pct
        limit = len(acc) if a.verbose else min(len(acc), 100)
        print("cell  rate_kg_ha  M1_g     M2_g     accuracy_%")
        for i in range(limit):
            print(
                f"{int(seqs[i]):5d} {res.extra['rate'][i]:8.1f} {res.cell_m1_g[i]:9.1f}"
                f" {res.cell_m2_g[i]:9.1f}   {acc[i]:6.2f}"
            )
        if limit < len(acc):
            print(f"... {len(acc) - limit} more cells (--cells-out FILE for all)")
        print(
            f"mean accuracy {out['mean_accuracy_pct']} %, min {out['min_accuracy_pct']} %;"
            f" mean lag at borders {out['mean_lag_m']} m (uncompensated"
            f" {out.get('mean_lag_uncompensated_m')} m); outside the field"
            f" {out['applied_outside_kg']} kg; {np.round(res.wall_s, 1)} s"
        )
    if a.json:
        print(json.dumps(out))
    return 0


# -- upload-log -------------------------------------------------------------


def cmd_upload_log(a: argparse.Namespace) -> int:
    """Upload thin-profile jobs' full 10 Hz logs, one gzip file per job: the jobs named, or
    those the office requested (``GET /device/raw-logs/requested``)."""
    import httpx

    from fieldrx_edge.uplink.thin import pack_raw_log, raw_log_path

    store = JobStore(a.state_dir)
    cfg = store.config()
    server = a.server or cfg.get("server")
    token = a.token or cfg.get("token")
    if not server or not token:
        raise SystemExit("upload-log needs --server and --token (or a saved config: pull)")
    base = server.rstrip("/") + "/api/v1/device"
    headers = {"Authorization": f"Bearer {token}"}
    with httpx.Client(headers=headers, timeout=a.timeout) as c:
        ids = a.job
        if not ids:
            r = c.get(base + "/raw-logs/requested")
            r.raise_for_status()
            ids = r.json()["job_ids"]
        out: dict[str, Any] = {"uploaded": {}, "missing": [], "failed": {}}
        for jid in ids:
            path = raw_log_path(store.root, jid)
            if not path.exists():
                out["missing"].append(jid)  # not run thin on this tractor
                continue
            r = c.put(
                f"{base}/jobs/{jid}/raw-log",
                content=pack_raw_log(path),
                headers={"Content-Type": "application/gzip"},
            )
            if r.status_code >= 400:
                out["failed"][str(jid)] = f"HTTP {r.status_code}: {r.text[:200]}"
            else:
                out["uploaded"][str(jid)] = r.json()["records"]
    print(json.dumps(out))
    return 1 if out["failed"] else 0


# -- replay-nmea ------------------------------------------------------------


def replay_stats(lines: Any) -> dict[str, Any]:
    """Parse a log through the GNSS front end; counts plus raw vs Kalman speed spread."""
    from fieldrx_edge.estimate import KalmanSpeedFilter
    from fieldrx_edge.gnss.parser import NmeaParser

    parser = NmeaParser()
    kf = KalmanSpeedFilter()
    raw: list[float] = []
    filt: list[float] = []
    t_first = t_last = None

    def take(fx: Any) -> None:
        nonlocal t_first, t_last
        if fx.valid and fx.speed_m_s is not None:
            raw.append(fx.speed_m_s)
            filt.append(kf.update(fx.speed_m_s))
        if fx.t is not None:
            t_first = fx.t if t_first is None else t_first
            t_last = fx.t

    for line in lines:
        for fx in parser.feed(line):
            take(fx)
    for fx in parser.flush():
        take(fx)

    def std(v: list[float]) -> float | None:
        if len(v) < 2:
            return None
        m = sum(v) / len(v)
        return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))

    out = parser.stats.to_dict()
    out.update(
        {
            "speed_raw_mean": (sum(raw) / len(raw)) if raw else None,
            "speed_raw_std": std(raw),
            "speed_filtered_mean": (sum(filt) / len(filt)) if filt else None,
            "speed_filtered_std": std(filt),
            "duration_s": (t_last - t_first) if t_first is not None and t_last else None,
        }
    )
    return out


def cmd_replay(a: argparse.Namespace) -> int:
    from fieldrx_edge.gnss.sources import file_lines

    speed = a.speed if a.speed > 0 else None
    out = replay_stats(file_lines(a.log, speed))
    if not a.json:
        print(f"lines {out['lines']}, fixes {out['fixes']} (no fix {out['no_fix']})")
        print(f"sentences {out['sentences']}, other {out['other_sentences']}")
        print(f"bad checksum {out['bad_checksum']}, malformed {out['malformed']}")
        print(
            f"out of range {out['out_of_range']}, non-finite {out['non_finite']}, "
            f"resync after binary {out['resync']}, talkers {out['talkers']}"
        )
        print(f"fix quality {out['fix_quality']}")
        print(f"speed std raw {out['speed_raw_std']} m/s, filtered {out['speed_filtered_std']} m/s")
    else:
        print(json.dumps(out))
    return 0


# -- ndvi -----------------------------------------------------------------


def cmd_ndvi(a: argparse.Namespace) -> int:
    from fieldrx_edge.gnss.sources import open_source
    from fieldrx_edge.motor import MotorLoop, build_controller, simulated_motor
    from fieldrx_edge.ndvi import GnssSpeed, NdviMode, run_ndvi
    from fieldrx_edge.protocol import ControllerSettings

    mode = NdviMode(width_m=a.width)
    speed: Any = (
        GnssSpeed(open_source(a.gnss, a.replay_speed or None)) if a.gnss else a.speed_kmh / 3.6
    )
    queue = sender = None
    stop = threading.Event()
    if a.machine_id:
        from fieldrx_edge.uplink import TelemetryQueue

        store = JobStore(a.state_dir)
        queue = TelemetryQueue(store.queue_path(), a.machine_id)
        sender = _make_sender(a, store, queue)
        if sender is not None:
            threading.Thread(target=sender.run, args=(stop,), daemon=True).start()
    # the job-less NDVI mode drives the simulated motor (or --controller isp, seed 000)
    settings = ControllerSettings(name=a.controller)
    motor = MotorLoop(build_controller(settings), simulated_motor(0.01), 0.01)
    mstop = threading.Event()
    threading.Thread(target=motor.run, args=(mstop,), daemon=True).start()
    rates: list[float] = []

    def show(d: Any) -> None:
        rates.append(d.rate_kg_ha)
        if not a.json:
            print(
                f"ndvi {d.ndvi_raw:.3f} -> {d.ndvi:.3f}  rate {d.rate_kg_ha:6.1f} kg/ha"
                f"  shaft {d.target_rpm:5.2f} r/min {' '.join(d.alarms)}"
            )

    n = run_ndvi(
        open_source(a.source, a.replay_speed or None),
        mode,
        speed,
        motor,
        queue,
        a.machine_id or 1,
        show,
    )
    mstop.set()
    out: dict[str, Any] = {
        "samples": n,
        "bad_lines": mode.bad_lines,
        "mean_rate_kg_ha": sum(rates) / n if n else None,
    }
    if queue is not None:
        if sender is not None:
            stop.set()
            out["drained"] = sender.drain(a.drain_timeout)
            sender.close()
        out["queue"] = queue.stats()
    if a.json:
        print(json.dumps(out))
    return 0


CAN_HELP = (
    "socketcan:can0, pcan:PCAN_USBBUS1, slcan:/dev/ttyACM0@500000, "
    "socketcand:HOST:PORT:CHANNEL, virtual:NAME (any python-can interface:channel)"
)


def _isobus_args(sp: argparse.ArgumentParser) -> None:
    sp.add_argument(
        "--implement",
        choices=("motor", "isobus"),
        default="motor",
        help="motor: --motor drives the meter; isobus: act as Task Controller on --can",
    )
    sp.add_argument("--can", help=CAN_HELP)
    sp.add_argument("--can-bitrate", type=int, default=250_000, help="ISOBUS: 250000")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fieldrx-edge",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("-v", "--log-level", default="WARNING")
    sub = p.add_subparsers(dest="cmd", required=True)

    sp = sub.add_parser("pull", help="download this machine's jobs (device token)")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, help="save the default uplink profile")
    sp.add_argument("--state-dir")
    sp.set_defaults(func=cmd_pull)

    sp = sub.add_parser("run", help="run a cached job from a GNSS source")
    sp.add_argument("job", help="cached job id, package file, or demo:35x23")
    sp.add_argument("--state-dir")
    sp.add_argument(
        "--source",
        default="serial:/dev/ttyACM0",
        help="file:LOG, serial:DEV[@baud], tcp:HOST:PORT, udp:PORT",
    )
    sp.add_argument(
        "--replay-speed",
        type=float,
        default=1.0,
        help="file sources: 1 = recorded pace, 0 = as fast as possible",
    )
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument(
        "--mqtt",
        help="HOST:PORT: send telemetry over MQTT instead of HTTP"
        " (user machine-ID, password: the device token)",
    )
    sp.add_argument("--mqtt-ca", help="CA certificate file: connect to the broker over TLS")
    sp.add_argument("--offline", action="store_true", help="queue telemetry only")
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, help=UPLINK_HELP)
    sp.add_argument("--upload-period", type=float, help=UPLOAD_PERIOD_HELP)
    sp.add_argument("--motor", default="sim", help="sim or serial:DEV")
    sp.add_argument("--controller")
    sp.add_argument("--lag-compensation", type=_on_off, default=True)
    sp.add_argument("--response-s", type=float, help="motor response added to the look-ahead")
    sp.add_argument("--drain-timeout", type=float, default=30.0)
    sp.add_argument("--early-start", action="store_true", help="anticipate shaft spin-up")
    sp.add_argument("--min-fix-quality", type=int, default=1, help="GGA quality (4 = RTK fixed)")
    sp.add_argument("--max-hdop", type=float, default=5.0, help="0 disables the HDOP check")
    _isobus_args(sp)
    sp.add_argument("--tc-address", type=_address, default=0xF7, help="preferred TC source address")
    sp.add_argument(
        "--density", type=float, help="kg/l: lets volume-rate implements (DDI 1) be driven"
    )
    sp.add_argument("--sensor", help="sensor jobs: NDVI / depth sensor source (serial: or file:)")
    sp.set_defaults(func=cmd_run)

    sp = sub.add_parser("ecu", help="rate ECU: the motor loop as an ISOBUS TC client")
    sp.add_argument("--can", required=True, help=CAN_HELP)
    sp.add_argument("--can-bitrate", type=int, default=250_000)
    sp.add_argument("--job", help="job (id or file) for calibration, width and controller")
    sp.add_argument("--state-dir")
    sp.add_argument("--width", type=float, help="working width m (default: the job's, else 2.3)")
    sp.add_argument("--sections", type=int, default=1)
    sp.add_argument("--motor", default="sim", help="sim or serial:DEV")
    sp.add_argument("--controller")
    sp.add_argument("--address", type=_address, default=0x80, help="preferred source address")
    sp.add_argument("--identity", type=int, default=0x2A2, help="NAME identity number")
    sp.add_argument("--duration", type=float, default=0.0, help="stop after S seconds (0: never)")
    sp.set_defaults(func=cmd_ecu)

    sp = sub.add_parser("simulate", help="drive a job in simulation")
    sp.add_argument("job", help="package file, or demo:35x23 / demo:20ha")
    sp.add_argument("--speed", type=_speed_range, default=(3.0, 9.0))
    sp.add_argument("--gnss-noise", type=float, default=0.02, help="position noise, m (1 sigma)")
    sp.add_argument("--speed-noise", type=float, default=0.064, help="speed noise, m/s (1 sigma)")
    sp.add_argument("--gnss-hz", type=float, default=10.0)
    sp.add_argument("--controller")
    sp.add_argument("--lag-compensation", type=_on_off, default=True)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument(
        "--compare-runs", type=int, default=20, help="swaths re-driven without compensation"
    )
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--state-dir")
    sp.add_argument("--drain-timeout", type=float, default=60.0)
    sp.add_argument("--uplink", choices=UPLINK_PROFILES, default="full", help=UPLINK_HELP)
    sp.add_argument("--upload-period", type=float, help=UPLOAD_PERIOD_HELP)
    sp.add_argument("--realtime", type=float, default=0.0, help="pace: 1 = real time, 10 = 10x")
    sp.add_argument(
        "--sensor-fault", type=float, nargs=2, metavar=("FROM_S", "TO_S"),
        help="sensor jobs: the sensor falls silent between these drive times",
    )  # fmt: skip
    sp.add_argument("--cells-out")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--verbose", action="store_true")
    sp.add_argument(
        "--implement",
        choices=("direct", "isobus"),
        default="direct",
        help="isobus: the motor sits behind a rate ECU, driven by the TC over a virtual CAN bus",
    )
    sp.add_argument("--sections", type=int, default=1, help="isobus: sections of the rate ECU")
    sp.set_defaults(func=cmd_simulate)

    sp = sub.add_parser(
        "upload-log", help="upload thin jobs' 10 Hz logs (given, else those requested)"
    )
    sp.add_argument("job", nargs="*", type=int, help="job ids (default: the requested ones)")
    sp.add_argument("--state-dir")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--timeout", type=float, default=300.0)
    sp.set_defaults(func=cmd_upload_log)

    sp = sub.add_parser("replay-nmea", help="parse a receiver log and report")
    sp.add_argument("log")
    sp.add_argument("--speed", type=float, default=0.0, help="0 = as fast as possible")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_replay)

    sp = sub.add_parser("ndvi", help="seed 000 NDVI mode on a sensor log or serial port")
    sp.add_argument("source")
    sp.add_argument("--speed-kmh", type=float, default=6.0)
    sp.add_argument("--width", type=float, default=3.6)
    sp.add_argument("--gnss", help="GNSS source for the speed (else --speed-kmh)")
    sp.add_argument("--replay-speed", type=float, default=0.0, help="file sources: 0 = fast")
    sp.add_argument("--controller", default="ladrc")
    sp.add_argument("--machine-id", type=int, help="queue telemetry as this machine")
    sp.add_argument("--state-dir")
    sp.add_argument("--server")
    sp.add_argument("--token")
    sp.add_argument("--mqtt")
    sp.add_argument("--mqtt-ca")
    sp.add_argument("--offline", action="store_true")
    sp.add_argument("--drain-timeout", type=float, default=30.0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_ndvi)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=getattr(logging, str(args.log_level).upper(), logging.WARNING))
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
