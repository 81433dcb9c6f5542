"""POST /api/v1/telemetry: dedup, acked_seq with gaps, per-record rejects, machine scoping."""

from __future__ import annotations

import json
import time

import pytest
from fieldrx_edge.jobkinds.settings import validate_settings
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


def _cells_applied(db, job_id: int) -> int:  # noqa: ANN001
    db.expire_all()
    return db.execute(
        text("SELECT cells_applied FROM jobs WHERE id = :j"), {"j": job_id}
    ).scalar_one()


def test_progress_counts_cells_by_kind(client, db, org) -> None:  # noqa: ANN001
    """A seeding job reports no fertilizer rate, so progress stayed at 0 %. A sensor
    kind counts a cell once the implement has worked in it; a prescription job still needs a
    positive applied rate."""
    rx = make_job(org.id, state="running")
    _post(client, rx, [record(rx, 1, cell=0, applied_rate_kg_ha=0.0)])
    assert _cells_applied(db, rx.job_id) == 0  # driven, nothing landed: not applied
    _post(client, rx, [record(rx, 2, cell=0), record(rx, 3, cell=1, applied_rate_kg_ha=0.0)])
    assert _cells_applied(db, rx.job_id) == 1

    sd = make_job(org.id, state="running")
    # the plan read first: one statement mixing the coordinator's prescriptions and the
    # distributed jobs is refused past one node (Citus)
    plan_id = db.execute(
        text("SELECT plan_id FROM prescriptions WHERE id = (SELECT prescription_id FROM jobs"
             " WHERE machine_id = :m AND id = :j)"),
        {"m": sd.machine_id, "j": sd.job_id},
    ).scalar_one()
    db.execute(
        text(
            "UPDATE jobs SET kind = 'seeding_depth', settings = CAST(:s AS jsonb), plan_id = :p"
            " WHERE machine_id = :m AND id = :j"
        ),
        {"m": sd.machine_id, "j": sd.job_id, "p": plan_id,
         "s": json.dumps(validate_settings("seeding_depth", {}))},
    )
    db.commit()
    seeding = {"target_rate_kg_ha": None, "applied_rate_kg_ha": None, "depth_mm": 30.0}
    _post(client, sd, [record(sd, i, cell=i // 3, **seeding) for i in range(6)])  # cells 0, 1
    assert _cells_applied(db, sd.job_id) == 2
    batch = [record(sd, 6, cell=1, **seeding), record(sd, 7, cell=2, **seeding)]
    batch.append(record(sd, 8, cell=3, implement_down=False, **seeding))  # raised: not worked
    _post(client, sd, batch)
    assert _cells_applied(db, sd.job_id) == 3  # cell 1 once, cell 2 new, cell 3 not worked


# poison records, future times, streams --------------------------


def _raw(client, fx, body: str):  # noqa: ANN001, ANN202
    return client.post(
        "/api/v1/telemetry",
        content=body.encode(),
        headers={**fx.device_headers, "Content-Type": "application/json"},
    )


def test_nan_and_infinity_tokens_reject_only_their_records(client, db, job) -> None:  # noqa: ANN001
    """An older agent's queue can hold NaN/Infinity (Python's json.dumps writes them). They
    used to make the whole batch a 422, forever: that tractor's uplink was blocked."""
    recs = [json.dumps(record(job, s)) for s in range(1, 6)]
    recs[1] = json.dumps(record(job, 2, hdop=float("nan")))
    recs[3] = json.dumps(record(job, 4, speed_raw_m_s=float("inf"), duty=float("-inf")))
    assert "NaN" in recs[1] and "Infinity" in recs[3]
    r = _raw(client, job, '{"records": [' + ",".join(recs) + "]}")
    assert r.status_code == 200, r.text
    a = r.json()
    assert (a["stored"], a["acked_seq"]) == (3, 5)
    reasons = {x["seq"]: x["reason"] for x in a["rejected"]}
    assert set(reasons) == {2, 4}
    assert "hdop" in reasons[2] and "finite" in reasons[2]
    assert "finite" in reasons[4]
    assert _count(db, job.machine_id) == 3
    assert set(a) == {"machine_id", "acked_seq", "stored", "duplicates", "rejected"}  # format 1


def test_future_record_rejected_and_never_the_latest_state(client, db, job) -> None:  # noqa: ANN001
    now = time.time()
    a = _post(
        client,
        job,
        [record(job, 1, t=now - 2), record(job, 2, t=4_070_000_000.0), record(job, 3, t=now - 1)],
    ).json()
    assert (a["stored"], a["acked_seq"]) == (2, 3)
    assert [x["seq"] for x in a["rejected"]] == [2]
    assert "ahead of the server clock" in a["rejected"][0]["reason"]
    # a small clock skew is tolerated
    a = _post(client, job, [record(job, 4, t=now + 60)]).json()
    assert a["stored"] == 1
    # a status already frozen by an old far-future record thaws with the next real one
    db.execute(
        text("UPDATE machine_status SET last_t = to_timestamp(4070000000) WHERE machine_id = :m"),
        {"m": job.machine_id},
    )
    db.commit()
    assert _post(client, job, [record(job, 5, t=now + 1, cell=3)]).json()["stored"] == 1
    st = db.execute(
        text(
            "SELECT extract(epoch FROM last_t)::float8, cell_seq FROM machine_status"
            " WHERE machine_id = :m"
        ),
        {"m": job.machine_id},
    ).one()
    assert st[0] == pytest.approx(now + 1, abs=1e-3) and st[1] == 3


def _stream_post(client, fx, stream: str, records, start: int = 1):  # noqa: ANN001, ANN202
    body = {"format": 2, "stream": stream, "stream_start": start, "records": records}
    return client.post("/api/v1/telemetry", json=body, headers=fx.device_headers).json()


def test_streams_deduplicate_separately(client, db, job) -> None:  # noqa: ANN001
    """The same seqs on another stream are other records; on the same stream with
    the same fix time they are duplicates (a resend)."""
    a = _post(client, job, [record(job, s) for s in range(1, 11)]).json()  # legacy stream
    assert a["stored"] == 10
    b = _stream_post(
        client, job, "s1", [record(job, s, t=1_790_000_100.0 + s) for s in range(1, 11)]
    )
    assert (b["stored"], b["acked_seq"], b["stream"], b["stream_conflict"]) == (10, 10, "s1", False)
    b = _stream_post(
        client, job, "s1", [record(job, s, t=1_790_000_100.0 + s) for s in range(5, 13)]
    )
    assert (b["stored"], b["duplicates"], b["acked_seq"]) == (2, 6, 12)
    assert _count(db, job.machine_id) == 22
    # a stream migrated from an older queue starts where that queue's acks were
    c = _stream_post(
        client, job, "s2", [record(job, s, t=1_790_000_200.0 + s) for s in (41, 42)], start=41
    )
    assert (c["stored"], c["acked_seq"]) == (2, 42)


def test_seq_reused_on_a_known_stream_is_a_conflict_not_a_duplicate(client, db, job) -> None:  # noqa: ANN001
    a = _stream_post(
        client, job, "s1", [record(job, s, t=1_790_000_000.0 + s) for s in range(1, 21)]
    )
    assert a["acked_seq"] == 20
    # a restored copy numbers 16.. again with other records: 16-18 new content, 19-22 too
    b = _stream_post(
        client, job, "s1", [record(job, s, t=1_790_000_500.0 + s) for s in range(16, 23)]
    )
    assert b["stream_conflict"] is True
    assert b["stored"] == 0 and b["acked_seq"] == 15  # the agent may trim nothing it sent
    assert sorted(x["seq"] for x in b["rejected"]) == list(range(16, 23))
    assert all("went backwards" in x["reason"] for x in b["rejected"])
    assert _count(db, job.machine_id) == 20
    # the stored stream is untouched and still acknowledges its own resends
    c = _stream_post(
        client, job, "s1", [record(job, s, t=1_790_000_000.0 + s) for s in (19, 20, 21)]
    )
    assert (c["stream_conflict"], c["stored"], c["duplicates"], c["acked_seq"]) == (False, 1, 2, 21)


def test_bad_stream_or_format_is_a_422(client, job) -> None:  # noqa: ANN001
    for body in (
        {"stream": "../x", "records": []},
        {"stream": "a" * 33, "records": []},
        {"stream": "s", "stream_start": 0, "records": []},
        {"format": 3, "records": []},
    ):
        r = client.post("/api/v1/telemetry", json=body, headers=job.device_headers)
        assert r.status_code == 422, body


def test_fast_ingest_route_answers_as_the_documented_route(app, client, org, job) -> None:  # noqa: ANN001
    """POST /telemetry is served by a plain Starlette route matched before every router
    (fieldrx.api.telemetry.ingest_route: FastAPI's dependency solving and router walk were
    a third of the worker's CPU per thin request); its answers must be the documented
    FastAPI route's, header parsing and errors included."""
    from fastapi.routing import APIRoute
    from fastapi.testclient import TestClient
    from fieldrx.app import create_app
    from starlette.routing import Match

    scope = {"type": "http", "path": "/api/v1/telemetry", "method": "POST"}
    first = app.router.routes[0]
    assert not isinstance(first, APIRoute) and first.matches(scope)[0] is Match.FULL

    documented = create_app()
    del documented.router.routes[0]  # without the fast route: the FastAPI route serves
    token = job.device_headers["Authorization"].split(" ", 1)[1]
    cases = [
        {},
        {"Authorization": "Basic " + token},
        {"Authorization": "Bearer"},
        {"Authorization": "Bearer    "},
        {"Authorization": "bearer nope"},
        {"Authorization": "BEARER " + token},
        {"Authorization": "Bearer  " + token + "  "},
        org.headers(),
    ]
    with TestClient(documented) as slow:
        for headers in cases:
            for body in (b'{"records":[]}', b"{nope"):
                a = client.post("/api/v1/telemetry", content=body, headers=headers)
                b = slow.post("/api/v1/telemetry", content=body, headers=headers)
                assert (a.status_code, a.json()) == (b.status_code, b.json()), headers
                assert a.headers.get("www-authenticate") == b.headers.get("www-authenticate")
                assert a.headers["content-type"] == b.headers["content-type"]
        assert client.get("/api/v1/telemetry").json() == slow.get("/api/v1/telemetry").json()


@pytest.mark.parametrize("streamed", [True, False])
def test_ack_json_is_the_protocol_ack(streamed: bool) -> None:
    """IngestResult.to_json writes the ack without ``asdict``: the same bytes as before,
    format 1 acks without the stream fields and flags."""
    from dataclasses import asdict

    import orjson
    from fieldrx.fleet.ingest.model import IngestResult

    r = IngestResult(
        7, 41, stored=3, duplicates=2, rejected=[{"seq": 5, "reason": "bad é"}],
        stream="s1", stream_conflict=True, streamed=streamed,
    )  # fmt: skip
    want = asdict(r.ack())
    if not streamed:
        del want["stream"], want["stream_conflict"], want["flagged"]
    assert r.to_json() == orjson.dumps(want)


def test_deeply_nested_body_is_a_clear_422(client, job) -> None:  # noqa: ANN001
    """A 200,000-deep array used to be a 500 (RecursionError in the fallback parser)."""
    body = b'{"records": ' + b"[" * 200_000 + b"]" * 200_000 + b"}"
    r = client.post("/api/v1/telemetry", content=body, headers=job.device_headers)
    assert r.status_code == 422, r.text[:300]
    assert "not valid JSON" in r.json()["detail"]


def test_viewer_cannot_ask_the_tractor_for_its_raw_log(client, org, job) -> None:  # noqa: ANN001
    """Asking a tractor to upload its log makes it work: a viewer (read only) may not."""
    url = f"/api/v1/jobs/{job.job_id}/raw-log/request"
    r = client.post(url, headers=org.headers("viewer"))
    assert r.status_code == 403, r.text
    assert client.post(url, headers=org.headers()).status_code == 202


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("heading_deg", 1e308),
        ("heading_deg", -5.0),
        ("hdop", -1.0),
        ("applied_rate_kg_ha", -500.0),
        ("target_rate_kg_ha", 1e9),
        ("ndvi", 3.0),
        ("speed_raw_m_s", -2.0),
    ],
)
def test_out_of_range_values_are_refused_not_stored_as_sent(client, db, job, field, value) -> None:  # noqa: ANN001
    """Every numeric field of a record is range-checked (heading 1e308, HDOP -1 and an
    applied rate of -500 used to be stored as sent)."""
    now = time.time()
    recs = [record(job, 1, t=now - 2), record(job, 2, t=now - 1, **{field: value})]
    a = _post(client, job, recs).json()
    assert a["stored"] == 1 and [x["seq"] for x in a["rejected"]] == [2], a
    assert field in a["rejected"][0]["reason"] and "range" in a["rejected"][0]["reason"]
    assert _count(db, job.machine_id) == 1
