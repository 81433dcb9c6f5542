"""POST /api/v1/telemetry: dedup, acked_seq with gaps, per-record rejects, machine scoping."""

from __future__ import annotations

from sqlalchemy import text

from tests.fleet.helpers import make_job, record


def _post(client, fx, records):  # noqa: ANN001, ANN202
    return client.post("/api/v1/telemetry", json={"records": records}, headers=fx.device_headers)


def _count(db, machine_id: int) -> int:  # noqa: ANN001
    return db.execute(
        text("SELECT count(*) FROM telemetry WHERE machine_id = :m"), {"m": machine_id}
    ).scalar_one()


def test_same_batch_twice_is_stored_once(client, db, job) -> None:  # noqa: ANN001
    batch = [record(job, i, cell=(i - 1) % 8) for i in range(1, 51)]
    r1 = _post(client, job, batch)
    assert r1.status_code == 200, r1.text
    a1 = r1.json()
    assert a1 == {
        "machine_id": job.machine_id,
        "acked_seq": 50,
        "stored": 50,
        "duplicates": 0,
        "rejected": [],
    }
    a2 = _post(client, job, batch).json()
    assert (a2["acked_seq"], a2["stored"], a2["duplicates"]) == (50, 0, 50)
    assert _count(db, job.machine_id) == 50
    # the same seq twice inside one batch
    a3 = _post(client, job, [record(job, 51), record(job, 51)]).json()
    assert (a3["acked_seq"], a3["stored"], a3["duplicates"]) == (51, 1, 1)


def test_gap_stops_acked_seq_until_filled(client, db, job) -> None:  # noqa: ANN001
    a = _post(client, job, [record(job, i) for i in (1, 2, 3, 5, 6)]).json()
    assert (a["acked_seq"], a["stored"]) == (3, 5)
    a = _post(client, job, [record(job, 8)]).json()
    assert a["acked_seq"] == 3
    a = _post(client, job, [record(job, 4)]).json()
    assert a["acked_seq"] == 6  # 4 fills the gap, 5 and 6 were already stored; 7 missing
    a = _post(client, job, [record(job, 7)]).json()
    assert a["acked_seq"] == 8
    st = db.execute(
        text("SELECT acked_seq FROM machine_status WHERE machine_id = :m"), {"m": job.machine_id}
    ).scalar_one()
    assert st == 8


def test_bad_record_rejected_alone(client, db, job) -> None:  # noqa: ANN001
    good = [record(job, i) for i in range(1, 6)]
    bad = [
        record(job, 6, lon=200.0),
        record(job, 7, speed_raw_m_s="fast"),
        record(job, 8, alarms=["on_fire"]),
        {**record(job, 9), "colour": "red"},
        record(job, 10, job_id="x"),
    ]
    missing_t = record(job, 11)
    del missing_t["t"]
    a = _post(client, job, good + bad + [missing_t, record(job, 12)]).json()
    assert a["stored"] == 6
    reasons = {r["seq"]: r["reason"] for r in a["rejected"]}
    assert set(reasons) == {6, 7, 8, 9, 10, 11}
    assert "lon" in reasons[6] and "range" in reasons[6]
    assert "speed_raw_m_s" in reasons[7]
    assert "alarms" in reasons[8]
    assert "colour" in reasons[9]
    assert "job_id" in reasons[10]
    assert "'t'" in reasons[11]
    # rejected records can never be stored: they do not hold the ack back
    assert a["acked_seq"] == 12
    assert _count(db, job.machine_id) == 6


def test_device_cannot_write_other_machines_records(client, db, org) -> None:  # noqa: ANN001
    a, b = make_job(org.id), make_job(org.id)
    recs = [record(a, 1), record(b, 1), record(b, 2), record(a, 2)]
    ack = _post(client, a, recs).json()
    assert ack["machine_id"] == a.machine_id
    assert ack["stored"] == 2 and ack["acked_seq"] == 2
    assert [r["seq"] for r in ack["rejected"]] == [1, 2]
    assert all("not this device's machine" in r["reason"] for r in ack["rejected"])
    assert _count(db, b.machine_id) == 0
    # a user token cannot post telemetry at all
    assert (
        client.post("/api/v1/telemetry", json={"records": []}, headers=org.headers()).status_code
        == 403
    )
    assert client.post("/api/v1/telemetry", json={"records": []}).status_code == 401


def test_malformed_body(client, job) -> None:  # noqa: ANN001
    r = client.post("/api/v1/telemetry", content=b"{nope", headers=job.device_headers)
    assert r.status_code == 422 and "JSON" in r.json()["detail"]
    r = _post(client, job, None)
    assert r.status_code == 422 and "records" in r.json()["detail"]


def test_status_cells_and_progress(client, db, job) -> None:  # noqa: ANN001
    recs = [record(job, i, cell=(i - 1) // 5) for i in range(1, 21)]  # cells 0..3, 5 each
    recs[-1]["implement_down"] = False  # not counted in the cell aggregate
    _post(client, job, recs)
    rows = db.execute(
        text("SELECT seq, n_records FROM job_cells_applied WHERE job_id = :j ORDER BY seq"),
        {"j": job.job_id},
    ).all()
    assert [tuple(r) for r in rows] == [(0, 5), (1, 5), (2, 5), (3, 4)]
    applied = db.execute(
        text("SELECT cells_applied FROM jobs WHERE id = :j"), {"j": job.job_id}
    ).scalar_one()
    assert applied == 4
    _post(client, job, [record(job, 21, cell=3)])
    db.expire_all()
    assert (
        db.execute(
            text("SELECT cells_applied FROM jobs WHERE id = :j"), {"j": job.job_id}
        ).scalar_one()
        == 4
    )
    st = db.execute(
        text("SELECT acked_seq, cell_seq, lon FROM machine_status WHERE machine_id = :m"),
        {"m": job.machine_id},
    ).one()
    assert st.acked_seq == 21 and st.cell_seq == 3
    assert abs(st.lon - job.cells[3]["lon"]) < 1e-9
