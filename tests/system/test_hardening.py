"""Hostile input against a real API process: each abusive request is refused quickly with a
clear message while a concurrent health check keeps answering in < 100 ms."""

from __future__ import annotations

import io
import os
import socket
import threading
import time
import zipfile
from collections.abc import Callable, Iterator

import httpx
import pytest

from tests.fleet.procs import BIN, Proc, start_api
from tests.support import feature, scaled
from tests.support.plans import rectangle

API = "/api/v1"
# the server keeps answering health while a hostile upload is refused: a parse that blocked
# the event loop would take seconds; 100 ms on a quiet machine, scaled on a busy one (a
# quiet-ish run with 3 pytest workers and the browser tests beside it measured 105 ms)
HEALTH_BUDGET_S = scaled(0.100)
PLAN_TIME_LIMIT_S = 1.5


@pytest.fixture(scope="module")
def api(database_url: str) -> Iterator[str]:
    """A uvicorn API process with a short planning time limit (so the limit can be hit)."""
    env = {"FIELDRX_PLAN_TIME_LIMIT_S": str(PLAN_TIME_LIMIT_S), "FIELDRX_LIVE_TOKEN_CHECK_S": "0.5"}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        proc, url = start_api(database_url)
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    yield url
    proc.stop()


def _while_healthy(url: str, request: Callable[[], httpx.Response]) -> tuple[httpx.Response, float]:
    """Run ``request`` while another thread polls /health every 10 ms.

    Returns (response, the 90th-percentile health time) and checks that no health answer
    took a second or more (before the fix the server stopped answering for minutes).
    The 90th percentile keeps single scheduler stalls of a shared, overloaded test
    machine (load average 12 on 2 cores seen) from failing the budget check."""
    done = threading.Event()
    times: list[float] = []

    def poll() -> None:
        with httpx.Client(base_url=url, timeout=scaled(10)) as c:
            c.get(f"{API}/health")  # connect first: measure answers, not TCP set-up
            while not done.is_set():
                t0 = time.perf_counter()
                r = c.get(f"{API}/health")
                times.append(time.perf_counter() - t0)
                assert r.status_code == 200
                time.sleep(0.01)

    t = threading.Thread(target=poll, daemon=True)
    t.start()
    time.sleep(0.1)
    try:
        resp = request()
        # a refusal can be quicker than a busy machine schedules the poller: keep polling
        # until a few answers are in (the check is that health answers, not how often)
        end = time.perf_counter() + scaled(5)
        time.sleep(0.1)
        while len(times) < 3 and time.perf_counter() < end:
            time.sleep(0.01)
    finally:
        done.set()
        t.join(15)
    assert len(times) >= 3, "health was hardly answered"
    times.sort()
    p90 = times[int(0.9 * (len(times) - 1))]
    print(
        f"health during abuse: n={len(times)} median={times[len(times) // 2] * 1e3:.1f} ms "
        f"p90={p90 * 1e3:.1f} ms max={times[-1] * 1e3:.1f} ms"
    )
    assert times[-1] < 1.0, times[-5:]
    return resp, p90


def _field(url: str, headers: dict[str, str], geometry: dict) -> int:
    r = httpx.post(
        f"{url}{API}/fields", headers=headers, json=feature(geometry), timeout=scaled(30)
    )
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def test_million_row_soil_csv_is_refused_fast(api: str, org) -> None:  # noqa: ANN001
    h = org.headers()
    fid = _field(api, h, rectangle(112.30, 32.10, 300, 300))
    data = b"sample_id,lon,lat,n_mg_kg\n" + b"s,112.301,32.101,50\n" * 1_000_000
    assert len(data) < 20 * 1024 * 1024  # under the upload limit: the row count must refuse it

    def post() -> httpx.Response:
        files = {"file": ("big.csv", data, "text/csv")}
        return httpx.post(
            f"{api}{API}/fields/{fid}/soil-samples", headers=h, files=files, timeout=scaled(60)
        )

    t0 = time.perf_counter()
    r, worst = _while_healthy(api, post)
    took = time.perf_counter() - t0
    print(f"refused in {took * 1e3:.0f} ms")
    assert r.status_code == 422, r.text
    assert "1000000 rows, more than 50000" in r.json()["detail"]
    assert took < 5, took
    assert worst < HEALTH_BUDGET_S, worst
    listed = httpx.get(
        f"{api}{API}/fields/{fid}/soil-samples", headers=h, timeout=scaled(30)
    ).json()
    assert listed["total"] == 0


def _bomb(member: str, size: int) -> bytes:
    """A zip whose one member inflates to ``size`` bytes of zeros (about 1 MB per GiB)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        with z.open(member, "w", force_zip64=True) as f:
            chunk = b"\0" * (1 << 20)
            for _ in range(size >> 20):
                f.write(chunk)
    return buf.getvalue()


@pytest.mark.parametrize(("name", "member"), [("bomb.zip", "fields.shp"), ("bomb.kmz", "doc.kml")])
def test_zip_bomb_is_refused_fast(api: str, org, name: str, member: str) -> None:  # noqa: ANN001
    h = org.headers()
    data = _bomb(member, 1 << 30)
    assert len(data) < 2 * 1024 * 1024

    def post() -> httpx.Response:
        files = {"file": (name, data, "application/zip")}
        return httpx.post(f"{api}{API}/fields/import", headers=h, files=files, timeout=scaled(60))

    t0 = time.perf_counter()
    r, worst = _while_healthy(api, post)
    took = time.perf_counter() - t0
    print(f"refused in {took * 1e3:.0f} ms")
    assert r.status_code == 422, r.text
    assert "inflates to more than 256 MiB" in r.json()["detail"]
    assert took < 5, took
    assert worst < HEALTH_BUDGET_S, worst


def test_zip_member_lying_about_its_size_is_refused(api: str, org) -> None:  # noqa: ANN001
    """A central directory that declares a small size cannot smuggle a bomb past the count."""
    h = org.headers()
    data = bytearray(_bomb("doc.kml", 300 << 20))
    # patch the declared uncompressed size (central directory, zip64 extra) to 1 KiB
    cd = data.rfind(b"PK\x01\x02")
    extra_at = data.find(b"\x01\x00", cd + 46)  # zip64 extra block id 0x0001
    data[extra_at + 4 : extra_at + 12] = (1024).to_bytes(8, "little")
    files = {"file": ("liar.kmz", bytes(data), "application/zip")}
    r = httpx.post(f"{api}{API}/fields/import", headers=h, files=files, timeout=scaled(60))
    assert r.status_code == 422, r.text


def test_tiny_swath_plan_is_refused_before_work(api: str, org) -> None:  # noqa: ANN001
    h = org.headers()
    fid = _field(api, h, rectangle(112.30, 32.10, 2236, 2236))  # 500 ha

    def post() -> httpx.Response:
        body = {"swath_width_m": 0.05, "cell_length_m": 5.0}
        return httpx.post(
            f"{api}{API}/fields/{fid}/plans", headers=h, json=body, timeout=scaled(60)
        )

    t0 = time.perf_counter()
    r, worst = _while_healthy(api, post)
    took = time.perf_counter() - t0
    print(f"refused in {took * 1e3:.0f} ms")
    assert r.status_code == 422, r.text
    assert "more than 5000000" in r.json()["detail"]
    assert "use a wider swath or longer cells" in r.json()["detail"]
    assert took < 2, took
    assert worst < HEALTH_BUDGET_S, worst


def test_plan_over_the_time_limit_is_stopped_and_leaves_nothing(
    api: str,
    org,
    db,  # noqa: ANN001
) -> None:
    """Within the cell bound but slower than the time limit: the worker is killed, 422."""
    from sqlalchemy import text

    h = org.headers()
    fid = _field(api, h, rectangle(112.30, 32.10, 3000, 3000))  # 900 ha, ~1.5 M cells

    def post() -> httpx.Response:
        body = {"swath_width_m": 1.2, "cell_length_m": 5.0}
        return httpx.post(
            f"{api}{API}/fields/{fid}/plans", headers=h, json=body, timeout=scaled(60)
        )

    t0 = time.perf_counter()
    r, worst = _while_healthy(api, post)
    took = time.perf_counter() - t0
    print(f"refused in {took * 1e3:.0f} ms")
    assert r.status_code == 422, r.text
    assert f"longer than the {PLAN_TIME_LIMIT_S:g} s limit" in r.json()["detail"]
    assert took < PLAN_TIME_LIMIT_S + scaled(1.5), took  # the limit, then the stop
    assert worst < HEALTH_BUDGET_S, worst
    n = db.scalar(text("SELECT count(*) FROM plans WHERE field_id = :f"), {"f": fid})
    assert n == 0
    # the server still plans a normal request afterwards (a small field: well inside the
    # 1.5 s limit even on a busy machine)
    small = _field(api, h, rectangle(112.30, 32.10, 200, 200))
    ok = httpx.post(
        f"{api}{API}/fields/{small}/plans",
        headers=h,
        json={"swath_width_m": 24.0, "cell_length_m": 30.0},
        timeout=scaled(60),
    )
    assert ok.status_code == 201, ok.text


def test_hundred_megabyte_body_is_refused_before_it_is_read(api: str, org) -> None:  # noqa: ANN001
    """Content-Length over the limit: 413 after the headers, the body is never read."""
    host, port = api.removeprefix("http://").split(":")
    token = org.tokens["agronomist"]
    size = 100 * 1024 * 1024

    def post() -> httpx.Response:
        with socket.create_connection((host, int(port)), timeout=scaled(10)) as s:
            s.sendall(
                (
                    f"POST {API}/fields HTTP/1.1\r\nHost: {host}\r\n"
                    f"Authorization: Bearer {token}\r\nContent-Type: application/json\r\n"
                    f"Content-Length: {size}\r\n\r\n"
                ).encode()
                + b'{"type": "Feature", "properties": {"notes": "'
                + b"x" * (1 << 20)
            )
            raw = b""
            while b"\r\n\r\n" not in raw or not raw.rstrip().endswith(b"}"):
                chunk = s.recv(65536)
                if not chunk:
                    break
                raw += chunk
        head, _, body = raw.partition(b"\r\n\r\n")
        status = int(head.split()[1])
        return httpx.Response(status, content=body)

    t0 = time.perf_counter()
    r, worst = _while_healthy(api, post)
    assert r.status_code == 413, r.text
    assert "request body larger than 16 MiB" in r.json()["detail"]
    assert time.perf_counter() - t0 < 2
    assert worst < HEALTH_BUDGET_S, worst


def test_streamed_body_over_the_limit_is_413(api: str, org) -> None:  # noqa: ANN001
    """No Content-Length (chunked): counted while it streams in."""
    h = {**org.headers(), "Content-Type": "application/json"}

    def body() -> Iterator[bytes]:
        yield b'{"type": "Feature", "properties": {"notes": "'
        for _ in range(20):
            yield b"x" * (1 << 20)
        yield b'"}}'

    try:
        r = httpx.post(f"{api}{API}/fields", headers=h, content=body(), timeout=scaled(30))
    except httpx.WriteError:  # the server may answer and close before all chunks are sent
        pytest.skip("connection closed before the response could be read")
    assert r.status_code == 413, r.text


def test_long_notes_field_is_422(api: str, org) -> None:  # noqa: ANN001
    feat = feature(rectangle(112.30, 32.10, 200, 200), notes="x" * 1_000_000)
    r = httpx.post(f"{api}{API}/fields", headers=org.headers(), json=feat, timeout=scaled(30))
    assert r.status_code == 422, r.text
    assert "notes" in r.json()["detail"]


def test_security_headers_and_csp(api: str) -> None:
    r = httpx.get(f"{api}/", timeout=scaled(10))
    csp = r.headers["content-security-policy"]
    assert "default-src 'self'" in csp and "worker-src 'self' blob:" in csp
    assert "frame-ancestors 'none'" in csp
    assert r.headers["x-content-type-options"] == "nosniff"
    assert r.headers["x-frame-options"] == "DENY"
    h = httpx.get(f"{api}{API}/health", timeout=scaled(10))
    assert h.headers["x-content-type-options"] == "nosniff"


def test_health_does_not_disclose_versions(api: str) -> None:
    body = httpx.get(f"{api}{API}/health", timeout=scaled(10)).json()
    assert body == {"status": "ok", "database": "ok"}


def test_database_outage_is_503(database_url: str) -> None:
    """An API whose database is unreachable answers 503 with Retry-After, not 500."""
    bad = database_url.rsplit("/", 1)[0].replace("127.0.0.1:5432", "127.0.0.1:1") + "/nowhere"
    proc = Proc(
        [
            str(BIN / "uvicorn"),
            "fieldrx.app:create_app",
            "--factory",
            "--port",
            "0",
        ],
        {"DATABASE_URL": bad},
    )
    try:
        proc.wait_for("Uvicorn running on")
        line = next(x for x in proc.lines if "Uvicorn running on" in x)
        url = line.split("running on ")[1].split()[0]
        r = httpx.get(f"{url}{API}/health", timeout=scaled(30))
        assert r.status_code == 503, r.text
        assert "database is unavailable" in r.json()["detail"]
        assert r.headers["retry-after"]
    finally:
        proc.stop()


@pytest.mark.parametrize(
    "body",
    [
        {"swath_width_m": 5e-324, "cell_length_m": 5.0},
        {"swath_width_m": 1e-320, "cell_length_m": 1e300},
        {"swath_width_m": 2.0, "cell_length_m": 5e-324},
    ],
)
def test_degenerate_plan_parameters_are_422(api: str, org, body: dict) -> None:  # noqa: ANN001
    h = org.headers()
    fid = _field(api, h, rectangle(112.30, 32.10, 300, 300))
    r = httpx.post(f"{api}{API}/fields/{fid}/plans", headers=h, json=body, timeout=scaled(30))
    assert r.status_code == 422, r.text


def test_patch_racing_delete_never_answers_500(api: str, org) -> None:  # noqa: ANN001
    """40 rounds of PATCH and DELETE on the same field at once: 200/204/404/409, never 5xx."""
    from concurrent.futures import ThreadPoolExecutor

    h = org.headers()
    seen: list[int] = []
    c1 = httpx.Client(base_url=api, headers=h, timeout=scaled(30))
    c2 = httpx.Client(base_url=api, headers=h, timeout=scaled(30))
    with c1, c2, ThreadPoolExecutor(2) as ex:
        for i in range(40):
            fid = _field(api, h, rectangle(112.30, 32.10 + i * 0.01, 200, 200))
            patch = ex.submit(
                c1.patch, f"{API}/fields/{fid}", json={"properties": {"notes": f"round {i}"}}
            )
            delete = ex.submit(c2.delete, f"{API}/fields/{fid}")
            seen += [patch.result().status_code, delete.result().status_code]
    assert all(s < 500 for s in seen), seen
    assert set(seen) <= {200, 204, 404, 409}, seen


def test_revoking_a_token_closes_its_live_socket(api: str, org) -> None:  # noqa: ANN001
    """The live socket authenticated by the subprotocol closes (4401) once its token is
    revoked; before, it stayed open until the browser left."""
    import asyncio

    import websockets

    login = httpx.post(
        f"{api}{API}/auth/login",
        json={"email": org.email("viewer"), "password": org.password},
        timeout=scaled(30),
    ).json()
    token = login["access_token"]
    ws_url = api.replace("http", "ws") + f"{API}/live"

    async def run() -> tuple[int | None, float]:
        async with websockets.connect(ws_url, subprotocols=["fieldrx", token]) as ws:
            assert ws.subprotocol == "fieldrx"
            first = await asyncio.wait_for(ws.recv(), 10)
            assert '"status"' in first
            r = httpx.post(
                f"{api}{API}/auth/logout",
                headers={"Authorization": f"Bearer {token}"},
                timeout=scaled(10),
            )
            assert r.status_code == 204
            t0 = time.perf_counter()
            try:
                while True:
                    await asyncio.wait_for(ws.recv(), 10)
            except websockets.ConnectionClosed as exc:
                return exc.rcvd.code if exc.rcvd else None, time.perf_counter() - t0

    code, took = asyncio.run(run())
    assert code == 4401
    assert took < 3, took


def test_live_tokens_are_not_written_to_the_log(database_url: str, org) -> None:  # noqa: ANN001
    """uvicorn logs every WebSocket URL; a ``?token=`` there is redacted."""
    import asyncio

    import websockets

    from tests.fleet.procs import free_port

    port = free_port()
    proc = Proc(
        [
            str(BIN / "uvicorn"),
            "fieldrx.app:create_app",
            "--factory",
            "--port",
            str(port),
            "--log-level",
            "info",
        ],
        {"DATABASE_URL": database_url},
    )
    token = org.tokens["viewer"]
    try:
        proc.wait_for("Uvicorn running on")

        async def run() -> None:
            url = f"ws://127.0.0.1:{port}{API}/live?token={token}"
            async with websockets.connect(url) as ws:
                await asyncio.wait_for(ws.recv(), 10)
            async with websockets.connect(
                f"ws://127.0.0.1:{port}{API}/live", subprotocols=["fieldrx", token]
            ) as ws:
                await asyncio.wait_for(ws.recv(), 10)

        asyncio.run(run())
        time.sleep(0.3)
    finally:
        out = proc.stop()
    assert "/live?token=[redacted]" in out, out[-2000:]
    assert token not in out


@pytest.mark.parametrize("path", ["/machines/status", "/alerts"])
def test_fleet_reads_do_not_queue_behind_the_alert_sweep_lock(
    api: str,
    org,
    database_url: str,
    path: str,  # noqa: ANN001
) -> None:
    """Before: every GET took the global advisory lock and waited while a sweep held it."""
    import psycopg

    assert (
        httpx.get(f"{api}{API}{path}", headers=org.headers(), timeout=scaled(10)).status_code == 200
    )
    with psycopg.connect(database_url.replace("+psycopg", "")) as conn:
        conn.execute("BEGIN")
        conn.execute("SELECT pg_advisory_xact_lock(7002, 0)")  # a long sweep elsewhere
        t0 = time.perf_counter()
        r = httpx.get(f"{api}{API}{path}", headers=org.headers(), timeout=scaled(10))
        took = time.perf_counter() - t0
        conn.execute("ROLLBACK")
    assert r.status_code == 200, r.text
    assert took < 1.0, took


def test_degenerate_meter_parameters_are_422_naming_the_field(client, org) -> None:  # noqa: ANN001
    """A 5e-324 m implement or speed is refused where it is entered, saying which value."""
    from tests.support.prescriptions import setup_plan

    h = org.headers()
    r = client.post("/api/v1/machines", headers=h, json={"name": "m", "width_m": 5e-324})
    assert r.status_code == 422 and "width_m" in r.json()["detail"], r.text
    plan = setup_plan(client, h)
    pid = plan["id"]
    for bad in ({"width_m": 5e-324}, {"speed_min_kmh": 1e-300, "speed_max_kmh": 1e-300}):
        body = {"model": "uniform", "params": {"rate_kg_ha": 200}, **bad}
        r = client.post(f"/api/v1/plans/{pid}/prescriptions", headers=h, json=body)
        assert r.status_code == 422, r.text
        assert next(iter(bad)) in r.json()["detail"]


def test_sigterm_stops_the_server_during_a_long_plan(database_url: str, org, db) -> None:  # noqa: ANN001
    """Before: a long plan held the server past SIGTERM. Now the server exits within its
    10 s graceful-shutdown time, the planning worker is killed and nothing is stored."""
    import signal

    from sqlalchemy import text

    from tests.fleet.procs import free_port

    port = free_port()
    proc = Proc(
        [str(BIN / "fieldrx"), "serve", "--port", str(port)],
        {"DATABASE_URL": database_url, "FIELDRX_PLAN_TIME_LIMIT_S": "300"},
    )
    api = f"http://127.0.0.1:{port}"
    try:
        proc.wait_for("Uvicorn running on")
        h = org.headers()
        fid = _field(api, h, rectangle(112.30, 32.10, 4000, 4000))  # 1,600 ha
        result: dict[str, object] = {}

        def plan() -> None:
            body = {"swath_width_m": 1.0, "cell_length_m": 5.0}
            try:
                r = httpx.post(
                    f"{api}{API}/fields/{fid}/plans", headers=h, json=body, timeout=scaled(120)
                )
                result["status"] = r.status_code
            except httpx.HTTPError as exc:
                result["error"] = repr(exc)

        t = threading.Thread(target=plan)
        t.start()
        time.sleep(3)
        t0 = time.perf_counter()
        proc.p.send_signal(signal.SIGTERM)
        proc.p.wait(60)
        took = time.perf_counter() - t0
        t.join(30)
    finally:
        proc.stop()
    assert took < 15, took
    assert result.get("status") != 201, result
    n = db.scalar(text("SELECT count(*) FROM plans WHERE field_id = :f"), {"f": fid})
    assert n == 0


def test_heavy_work_runs_under_a_long_tmpdir(database_url: str, org, tmp_path) -> None:  # noqa: ANN001
    """A server whose TMPDIR is too long for a Unix socket path (a CI job's own directory)
    still plans: the heavy-work forkserver keeps its socket in a short directory, while
    uploads are still spooled under TMPDIR."""
    tmp = tmp_path / ("t" * 80)
    tmp.mkdir()
    proc, url = start_api(database_url, env={"TMPDIR": str(tmp)})
    try:
        h = org.headers()
        fid = _field(url, h, rectangle(112.30, 32.10, 200, 200))
        r = httpx.post(
            f"{url}{API}/fields/{fid}/plans",
            headers=h,
            json={"swath_width_m": 24.0, "cell_length_m": 30.0},
            timeout=scaled(60),
        )
        assert r.status_code == 201, (r.text, proc.lines[-20:])
    finally:
        proc.stop()
