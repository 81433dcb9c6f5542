"""Uplink profile ``thin`` (1 Hz track + one record per cell left).

The same job driven twice by ``fieldrx-edge simulate --server`` (same seed, so the same
drive, shaft speeds and log), once with every fix (full) and once thin, by two machines
with the same settings: the server's reports must agree within 0.5 % (totals and every
cell), since the thin tractor ran the one as-applied kernel over the same 10 Hz log. The
thin job's telemetry holds about a tenth of the records; its cell records are kept in
their own table, acknowledged and deduplicated like telemetry.
"""

from __future__ import annotations

import gzip
import json
import subprocess
import time
from pathlib import Path

import httpx
import numpy as np
import psycopg
import pytest
from sqlalchemy import text

from tests.fleet.procs import BIN, ROOT, start_api
from tests.support import SEED001_CAL, SMALL_PLOT, feature, machine_body, scaled


def _job(c: httpx.Client, rx_id: int, name: str) -> tuple[int, str]:
    cal = {**SEED001_CAL, "min_rpm": 10.0}
    m = c.post("/api/v1/machines", json=machine_body(name, 2.3, calibration=cal)).json()
    token = c.post(f"/api/v1/machines/{m['id']}/device-token").json()["token"]
    return m["id"], token


def _simulate(url: str, tmp: Path, job_id: int, token: str, uplink: str) -> dict:
    dev = {"Authorization": f"Bearer {token}"}
    pkg = httpx.get(f"{url}/api/v1/device/jobs/{job_id}/package", headers=dev)
    assert pkg.status_code == 200, pkg.text
    path = tmp / f"job-{uplink}.json"
    path.write_bytes(pkg.content)
    out = subprocess.run(
        [str(BIN / "fieldrx-edge"), "simulate", str(path), "--server", url, "--token", token,
         "--json", "--seed", "5", "--state-dir", str(tmp / f"state-{uplink}"),
         "--compare-runs", "1", "--uplink", uplink],
        cwd=ROOT, capture_output=True, text=True, timeout=scaled(180),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("headland_passes", [0, 1], ids=["plain", "headland"])
def test_thin_report_equals_full(
    database_url: str,
    org,  # noqa: ANN001
    tmp_path: Path,
    headland_passes: int,
) -> None:
    api, url = start_api(database_url, env={"FIELDRX_RAW_LOG_DIR": str(tmp_path / "rawlogs")})
    try:
        c = httpx.Client(base_url=url, headers=org.headers(), timeout=scaled(60))
        field = c.post("/api/v1/fields", json=feature(SMALL_PLOT, name="trial plot")).json()
        plan = c.post(
            f"/api/v1/fields/{field['id']}/plans",
            json={"swath_width_m": 2.3, "cell_length_m": 5.0, "headland_passes": headland_passes},
        ).json()
        jobs: dict[str, tuple] = {}
        tokens: dict[str, str] = {}
        for uplink in ("full", "thin"):
            mid, token = _job(c, 0, f"sim-{uplink}")
            rx = c.post(
                f"/api/v1/plans/{plan['id']}/prescriptions",
                json={"model": "uniform", "params": {"rate_kg_ha": 300.0}, "machine_id": mid},
            ).json()
            n = len(c.get(f"/api/v1/plans/{plan['id']}/cells?limit=1000").json()["features"])
            edits = [{"seq": s, "rate_kg_ha": 220.0 + 40.0 * (s % 4)} for s in range(n)]
            r = c.post(f"/api/v1/prescriptions/{rx['id']}/edits", json={"cells": edits})
            assert r.status_code == 201, r.text
            job = c.post("/api/v1/jobs", json={"prescription_id": rx["id"], "machine_id": mid})
            job = job.json()
            c.post(f"/api/v1/jobs/{job['id']}/state", json={"state": "sent"})
            sim = _simulate(url, tmp_path, job["id"], token, uplink)
            assert sim["telemetry_drained"] is True
            assert sim["uplink"]["profile"] == uplink
            jobs[uplink] = (job["id"], mid, sim)
            tokens[uplink] = token
        reps = {u: c.get(f"/api/v1/jobs/{j[0]}/report").json() for u, j in jobs.items()}
        tiles = {
            u: c.get(f"/api/v1/jobs/{j[0]}/report?cells=true").json()["cells"]
            for u, j in jobs.items()
        }
        if not headland_passes:  # the 10 Hz log, kept on the tractor, uploaded on request
            jt = jobs["thin"][0]
            assert c.get(f"/api/v1/jobs/{jt}/raw-log").status_code == 404
            r = c.post(f"/api/v1/jobs/{jt}/raw-log/request")
            assert (r.status_code, r.json()["state"]) == (202, "requested")
            up = subprocess.run(
                [str(BIN / "fieldrx-edge"), "upload-log", "--state-dir",
                 str(tmp_path / "state-thin"), "--server", url, "--token", tokens["thin"]],
                cwd=ROOT, capture_output=True, text=True, timeout=scaled(60),
            )  # fmt: skip
            assert up.returncode == 0, up.stderr[-2000:]
            assert json.loads(up.stdout)["uploaded"] == {str(jt): reps["full"]["n_records"]}
            raw = c.get(f"/api/v1/jobs/{jt}/raw-log")
            assert raw.status_code == 200
            lines = gzip.decompress(raw.content).decode().splitlines()
            assert len(lines) == reps["full"]["n_records"]  # every fix, as the full job sent
            assert json.loads(lines[0])["job_id"] == jt
            # a device cannot upload a broken file, nor another machine's job's log
            dev = {"Authorization": f"Bearer {tokens['thin']}"}
            bad = httpx.put(f"{url}/api/v1/device/jobs/{jt}/raw-log", content=b"xx", headers=dev)
            assert bad.status_code == 422 and "gzip" in bad.text
            other = httpx.put(
                f"{url}/api/v1/device/jobs/{jobs['full'][0]}/raw-log",
                content=gzip.compress(b"{}\n"),
                headers=dev,
            )
            assert other.status_code == 404
    finally:
        api.stop()
    full, thin = reps["full"], reps["thin"]
    assert full["uplink"] == "full" and thin["uplink"] == "thin"
    keys = ("applied_total_kg", "applied_in_cells_kg", "applied_outside_cells_kg",
            "mean_accuracy_pct", "time_worked_s", "n_records")  # fmt: skip
    print({k: (full[k], thin[k]) for k in keys})
    for key in ("applied_total_kg", "applied_in_cells_kg", "planned_total_kg", "time_worked_s"):
        assert thin[key] == pytest.approx(full[key], rel=0.005), key
    assert thin["applied_outside_cells_kg"] == pytest.approx(
        full["applied_outside_cells_kg"], abs=0.005 * full["applied_total_kg"]
    )
    assert thin["mean_accuracy_pct"] == pytest.approx(full["mean_accuracy_pct"], abs=0.5)
    assert thin["cells_applied"] == full["cells_applied"]
    assert thin["not_applied_seqs"] == full["not_applied_seqs"]
    fc = {x["seq"]: x for x in tiles["full"]}
    tc = {x["seq"]: x for x in tiles["thin"]}
    assert fc.keys() == tc.keys()
    m2f = np.array([fc[s]["m2_g"] for s in fc])
    m2t = np.array([tc[s]["m2_g"] for s in fc])
    # every cell within 0.5 % of its planned mass
    m1 = np.array([max(fc[s]["m1_g"], 1.0) for s in fc])
    assert (np.abs(m2t - m2f) / m1).max() < 0.005
    acc = [(fc[s]["accuracy_pct"], tc[s]["accuracy_pct"]) for s in fc]
    assert all((a is None) == (b is None) for a, b in acc)
    assert max(abs(a - b) for a, b in acc if a is not None) < 0.5
    assert [fc[s]["n_records"] for s in fc] == [tc[s]["n_records"] for s in fc]
    # the thin job sent ~1 track record per second and ~1 record per cell worked
    with psycopg.connect(database_url.replace("+psycopg", "")) as conn:
        (jt, mt, _), (jf, _, _) = jobs["thin"], jobs["full"]
        nf = conn.execute("SELECT count(*) FROM telemetry WHERE job_id = %s", (jf,)).fetchone()[0]
        nt, with_cell = conn.execute(
            "SELECT count(*), count(cell_seq) FROM telemetry WHERE job_id = %s", (jt,)
        ).fetchone()
        nc, dup = conn.execute(
            "SELECT count(*), count(*) - count(DISTINCT (machine_id, stream, seq))"
            " FROM job_cell_records WHERE job_id = %s",
            (jt,),
        ).fetchone()
        acked = conn.execute(
            "SELECT acked_seq FROM cell_record_streams WHERE machine_id = %s", (mt,)
        ).fetchone()[0]
    assert nt * 8 < nf and with_cell == 0
    assert dup == 0 and nc == acked == jobs["thin"][2]["uplink"]["cells"]["last_seq"]
    assert len(fc) * 0.5 < nc < len(fc) * 3


def _cell(job, seq: int, cell: int | None, t: float, mass: float = 10.0) -> dict:  # noqa: ANN001
    return {
        "machine_id": job.machine_id, "seq": seq, "job_id": job.job_id, "cell_seq": cell,
        "t_entry": t, "t_exit": t + 1.5, "n_fixes": 15, "worked_s": 1.5, "mass_g": mass,
        "driven_m": 5.0, "mean_speed_m_s": 1.8, "mean_target_rate_kg_ha": 300.0,
        "mean_applied_rate_kg_ha": 298.0, "flags": [],
    }  # fmt: skip


def _post_cells(client, job, records: list[dict], stream: str = "cellsA") -> dict:  # noqa: ANN001
    body = {"format": 3, "kind": "cells", "stream": stream, "stream_start": 1, "records": records}
    r = client.post("/api/v1/telemetry", json=body, headers=job.device_headers)
    assert r.status_code == 200, r.text
    return r.json()


def test_cell_batches_dedup_and_ack_like_telemetry(client, db, job) -> None:  # noqa: ANN001
    t = time.time() - 100
    batch = [_cell(job, i, (i - 1) % 8, t + 2 * i) for i in range(1, 11)]
    a = _post_cells(client, job, batch)
    assert (a["acked_seq"], a["stored"], a["duplicates"], a["stream"]) == (10, 10, 0, "cellsA")
    a = _post_cells(client, job, batch)  # a resend (the ack was lost)
    assert (a["acked_seq"], a["stored"], a["duplicates"]) == (10, 0, 10)
    # a gap stops the ack until filled; a bad record is rejected alone and acked past
    a = _post_cells(
        client, job, [_cell(job, 12, 1, t + 40), {**_cell(job, 13, 2, t), "mass_g": -1}]
    )
    assert (a["acked_seq"], a["stored"]) == (10, 1)
    assert a["rejected"][0]["seq"] == 13 and "mass_g" in a["rejected"][0]["reason"]
    a = _post_cells(client, job, [_cell(job, 11, 1, t + 38)])
    assert a["acked_seq"] == 12  # as telemetry: 13 is acked past when resent behind no gap
    a = _post_cells(client, job, [{**_cell(job, 13, 2, t), "mass_g": -1}])
    assert (a["acked_seq"], a["stored"]) == (13, 0)
    # another record under a stored seq: the numbering went backwards
    a = _post_cells(client, job, [_cell(job, 5, 3, t + 60), _cell(job, 14, 3, t + 50)])
    assert (a["stream_conflict"], a["stored"], a["acked_seq"]) == (True, 0, 4), a
    # a job of another machine is refused
    a = _post_cells(client, job, [{**_cell(job, 1, 1, t), "job_id": job.job_id + 999}], "cellsB")
    assert a["stored"] == 0 and "not this machine's job" in a["rejected"][0]["reason"]
    n, distinct, mass = db.execute(
        text(
            "SELECT count(*), count(DISTINCT seq), sum(mass_g) FROM job_cell_records"
            " WHERE machine_id = :m"
        ),
        {"m": job.machine_id},
    ).one()
    assert (n, distinct, mass) == (12, 12, 120.0)
    # the cell records move the job's progress (cells 0..7 got a positive applied rate)
    applied = db.execute(
        text("SELECT cells_applied FROM jobs WHERE id = :j"), {"j": job.job_id}
    ).scalar_one()
    assert applied == 8
    # cell streams are not telemetry streams (a thin agent is not two agents)
    n = db.execute(
        text("SELECT count(*) FROM telemetry_streams WHERE machine_id = :m"),
        {"m": job.machine_id},
    ).scalar_one()
    assert n == 0


def test_track_and_cells_in_one_request(client, db, job) -> None:  # noqa: ANN001
    """A thin agent's track and cell batches in one request (protocol.MULTI_KIND): one
    ack per batch, in order, each stored and deduplicated as if sent alone."""
    from tests.fleet.helpers import record

    t = time.time() - 100
    track = {
        "format": 2, "stream": "trackM", "stream_start": 1,
        "records": [record(job, i, t=t + i, cell=None) for i in range(1, 6)],
    }  # fmt: skip
    cells = {
        "format": 3, "kind": "cells", "stream": "cellsM", "stream_start": 1,
        "records": [_cell(job, i, i - 1, t + 2 * i) for i in range(1, 4)],
    }  # fmt: skip
    body = {"format": 3, "kind": "batches", "batches": [track, cells]}
    for stored, dups in ((5, 0), (0, 5)):  # then a resend: the acks were lost
        r = client.post("/api/v1/telemetry", json=body, headers=job.device_headers)
        assert r.status_code == 200, r.text
        a, b = r.json()["acks"]
        assert (a["stream"], a["acked_seq"], a["stored"], a["duplicates"]) == (
            "trackM",
            5,
            stored,
            dups,
        )
        assert (b["stream"], b["acked_seq"], b["stored"]) == ("cellsM", 3, 3 if not dups else 0)
    n = db.execute(
        text("SELECT (SELECT count(*) FROM telemetry WHERE machine_id = :m),"
             " (SELECT count(*) FROM job_cell_records WHERE machine_id = :m)"),
        {"m": job.machine_id},
    ).one()  # fmt: skip
    assert tuple(n) == (5, 3)
    # a bad batch refuses the whole request, naming the batch; nothing more is stored
    bad = {**body, "batches": [track, {**cells, "stream": "no spaces"}]}
    r = client.post("/api/v1/telemetry", json=bad, headers=job.device_headers)
    assert r.status_code == 422 and "batches[1]" in r.text, r.text
    for wrong in ({**body, "format": 2}, {**body, "batches": []}, {**body, "batches": [body]}):
        r = client.post("/api/v1/telemetry", json=wrong, headers=job.device_headers)
        assert r.status_code == 422, r.text


def test_track_and_cells_share_one_transaction(client, db, job) -> None:  # noqa: ANN001
    """A track and a cell batch in one request are stored in one transaction (one lock
    round, one NOTIFY, one COMMIT: fleet.multibatch); a cell batch the database refuses
    does not take the track batch down: the track is stored and acked once, the cell batch
    gets an error naming it and the record, and none of its rows are stored."""
    from tests.fleet.helpers import on_citus, record

    t = time.time() - 100
    track = {
        "format": 2, "stream": "trackT", "stream_start": 1,
        "records": [record(job, i, t=t + i, cell=None) for i in range(1, 6)],
    }  # fmt: skip
    cells = {
        "format": 3, "kind": "cells", "stream": "cellsT", "stream_start": 1,
        "records": [_cell(job, i, i - 1, t + 2 * i) for i in range(1, 4)],
    }  # fmt: skip
    body = {"format": 3, "kind": "batches", "batches": [track, cells]}
    r = client.post("/api/v1/telemetry", json=body, headers=job.device_headers)
    assert r.status_code == 200, r.text
    assert [a["stored"] for a in r.json()["acks"]] == [5, 3]
    xids = db.execute(
        text("SELECT xmin::text FROM telemetry WHERE machine_id = :m AND stream = 'trackT'"
             " UNION SELECT xmin::text FROM job_cell_records WHERE machine_id = :m"),
        {"m": job.machine_id},
    ).scalars().all()  # fmt: skip
    assert len(xids) == 1, xids  # one transaction wrote both batches

    # a cell record the database refuses (a constraint this test adds): the shared
    # transaction fails, and each batch is stored on its own
    db.execute(text("ALTER TABLE job_cell_records ADD CONSTRAINT test_mass CHECK (mass_g < 1e6)"))
    db.commit()
    try:
        track2 = {**track, "records": [record(job, i, t=t + i, cell=None) for i in range(6, 9)]}
        bad_cells = [_cell(job, 4, 3, t + 8), _cell(job, 5, 4, t + 10, mass=5e6)]
        body2 = {**body, "batches": [track2, {**cells, "records": bad_cells}]}
        r = client.post("/api/v1/telemetry", json=body2, headers=job.device_headers)
        assert r.status_code == 200, r.text
        a, b = r.json()["acks"]
        assert (a["stream"], a["acked_seq"], a["stored"], a["duplicates"]) == ("trackT", 8, 3, 0)
        assert "error" not in a
        assert (b["stream"], b["acked_seq"], b["stored"]) == ("cellsT", 0, 0)
        assert "batches[1]" in b["error"] and "cellsT" in b["error"], b["error"]
        assert "test_mass" in b["error"], b["error"]
        # the COPY line of the refused record (Citus relays the worker's message without it)
        assert "line 2" in b["error"] or on_citus(db), b["error"]
        n = db.execute(
            text("SELECT count(*) FROM job_cell_records WHERE machine_id = :m AND seq > 3"),
            {"m": job.machine_id},
        ).scalar_one()
        assert n == 0  # not the first, valid record either: the batch is all or nothing
    finally:
        db.execute(text("ALTER TABLE job_cell_records DROP CONSTRAINT test_mass"))
        db.commit()
    # the agent resends both: the track batch is a duplicate (stored once), the cells go in
    r = client.post("/api/v1/telemetry", json=body2, headers=job.device_headers)
    a, b = r.json()["acks"]
    assert (a["acked_seq"], a["stored"], a["duplicates"]) == (8, 0, 3)
    assert (b["acked_seq"], b["stored"], "error" in b) == (5, 2, False)
    n = db.execute(
        text("SELECT (SELECT count(*) FROM telemetry WHERE machine_id = :m),"
             " (SELECT count(*) FROM job_cell_records WHERE machine_id = :m)"),
        {"m": job.machine_id},
    ).one()  # fmt: skip
    assert tuple(n) == (8, 5)


def test_cell_fast_path_agrees_with_cell_record_rules(monkeypatch) -> None:  # noqa: ANN001
    """cellrecords.validate's fast path (plainly typed records) stores, rejects and repeats
    exactly what ``CellRecord.from_dict`` alone does, record by record."""
    from fieldrx.fleet import cellrecords

    now = time.time()
    base = {
        "machine_id": 7, "seq": 1, "job_id": 3, "t_entry": now - 10.0, "t_exit": now - 8.5,
        "cell_seq": 4, "n_fixes": 15, "worked_s": 1.5, "mass_g": 10.0, "driven_m": 5.0,
        "mean_speed_m_s": 1.8, "mean_target_rate_kg_ha": 300.0,
        "mean_applied_rate_kg_ha": 298.0, "flags": ["rate_error"],
    }  # fmt: skip
    variants = [
        {}, {"cell_seq": None}, {"driven_m": None, "mean_speed_m_s": None}, {"flags": []},
        {"n_fixes": 0, "worked_s": 0.0, "mass_g": 0.0}, {"t_entry": now - 8.5},
        {"mass_g": -1.0}, {"mass_g": float("nan")}, {"worked_s": float("inf")},
        {"driven_m": -0.1}, {"machine_id": True}, {"machine_id": 8}, {"seq": 0},
        {"seq": 2**63}, {"job_id": 0}, {"t_entry": 10}, {"t_exit": now - 11.0},
        {"t_exit": now + 1e4}, {"cell_seq": 2**31}, {"cell_seq": 1.0}, {"n_fixes": -1},
        {"n_fixes": True}, {"flags": ["nope"]}, {"flags": "rate_error"}, {"mass_g": 10},
        {"extra": 1}, {"t_entry": float("nan")},
    ]  # fmt: skip
    raw: list = [{**base, **v, "seq": v.get("seq", i + 1)} for i, v in enumerate(variants)]
    raw += [dict(raw[0]), "not a record", {k: v for k, v in base.items() if k != "flags"}]
    fast_path = cellrecords._fast_cell
    taken = []
    monkeypatch.setattr(
        cellrecords, "_fast_cell", lambda *a: taken.append(fast_path(*a)) or taken[-1]
    )
    fast = cellrecords.validate(raw, 7, "cellsF", now)
    monkeypatch.setattr(cellrecords, "_fast_cell", lambda *a: None)
    slow = cellrecords.validate(raw, 7, "cellsF", now)
    assert fast == slow
    assert len(fast[0]) == 8 and fast[3] == 2  # stored-to-be, and the two repeats of seq 1
    assert sum(r is not None for r in taken) == 7  # 6 plainly typed valid ones + a repeat
