"""``upload-log``, ``replay-nmea`` and the job-less ``ndvi`` mode."""

from __future__ import annotations

import argparse
import json
import math
import threading
from typing import Any

from fieldrx_edge.jobs import JobStore
from fieldrx_edge.session import JobSession, UplinkOptions

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
    from fieldrx_edge.job_package import ControllerSettings
    from fieldrx_edge.motor import MotorLoop, build_controller, simulated_motor
    from fieldrx_edge.ndvi import GnssSpeed, NdviMode, run_ndvi

    mode = NdviMode(width_m=a.width)
    speed: Any = (
        GnssSpeed(open_source(a.gnss, a.replay_speed or None)) if a.gnss else a.speed_kmh / 3.6
    )
    session = None
    if a.machine_id:
        store = JobStore(a.state_dir)
        session = JobSession(
            None, UplinkOptions.from_args(a, store), store.queue_path(), machine_id=a.machine_id
        )
        session.start(report=False)
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
        session,
        a.machine_id or 1,
        show,
    )
    mstop.set()
    out: dict[str, Any] = {
        "samples": n,
        "bad_lines": mode.bad_lines,
        "mean_rate_kg_ha": sum(rates) / n if n else None,
    }
    if session is not None:
        up = session.close()
        if session.sender is not None:
            out["drained"] = up["drained"]
        out["queue"] = up["queue"]
    if a.json:
        print(json.dumps(out))
    return 0
