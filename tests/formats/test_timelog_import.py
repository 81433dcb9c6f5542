"""As-applied import of ISO 11783-10 TimeLogs and its round trip."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
from fieldrx.formats import FormatError
from fieldrx.formats.timelog import read_timelog

from tests.formats.test_asapplied_export import driven  # noqa: F401  (fixture)
from tests.support.plans import API


def _export(client, h, job_id) -> dict[str, bytes]:
    r = client.get(f"{API}/jobs/{job_id}/export?format=isoxml", headers=h)
    assert r.status_code == 200
    z = zipfile.ZipFile(io.BytesIO(r.content))
    return {n.split("/")[-1]: z.read(n) for n in z.namelist()}, r.content


def test_timelog_decodes_to_the_records(client, org, driven):  # noqa: F811
    fx, recs = driven
    files, _ = _export(client, org.headers(), fx.job_id)
    log = read_timelog("TLG00001", files["TLG00001.XML"], files["TLG00001.BIN"])
    assert len(log) == len(recs)
    np.testing.assert_allclose(log.t, [r["t"] for r in recs], atol=0.002)
    np.testing.assert_allclose(log.lat, [r["lat"] for r in recs], atol=2e-7)
    np.testing.assert_allclose(log.lon, [r["lon"] for r in recs], atol=2e-7)
    np.testing.assert_allclose(
        log.series(7, 0.01), [r["applied_rate_kg_ha"] for r in recs], atol=0.005
    )
    np.testing.assert_array_equal(log.series(141), [int(r["implement_down"]) for r in recs])
    with pytest.raises(FormatError, match="TLG00001.BIN: record .* is cut short"):
        read_timelog("TLG00001", files["TLG00001.XML"], files["TLG00001.BIN"][:-3])


def test_timelog_import_becomes_a_job_with_a_report(client, org, driven):  # noqa: F811
    fx, recs = driven
    h = org.headers()
    _, data = _export(client, h, fx.job_id)
    up = {"files": ("TASKDATA.zip", data, "application/zip")}
    url = f"{API}/imports/timelog?prescription_id={fx.prescription_id}"
    pre = client.post(url, headers=h, files=up)
    assert pre.status_code == 200, pre.text
    body = pre.json()
    (tl,) = body["timelogs"]
    assert tl["records"] == len(recs) and tl["with_position"] == len(recs)
    assert tl["ddis_used"] == [6, 7, 141, 397]
    no_width = client.post(f"{url}&confirm={body['sha256']}", headers=h, files=up)
    assert no_width.status_code == 422 and "width_m" in no_width.json()["detail"]
    ok = client.post(f"{url}&confirm={body['sha256']}&width_m=3", headers=h, files=up)
    assert ok.status_code == 201, ok.text
    job_id = ok.json()["created"]["job_id"]
    assert job_id != fx.job_id
    pts = client.get(f"{API}/jobs/{job_id}/as-applied?limit=1000", headers=h).json()
    assert pts["total"] == len(recs)
    got = [f["properties"]["applied_rate_kg_ha"] for f in pts["features"]]
    assert got == pytest.approx([r["applied_rate_kg_ha"] for r in recs], abs=0.005)
    rep = client.get(f"{API}/jobs/{job_id}/report", headers=h).json()
    orig = client.get(f"{API}/jobs/{fx.job_id}/report", headers=h).json()
    cells = {c["seq"]: c for c in rep["cells"]}
    ocells = {c["seq"]: c for c in orig["cells"]}
    # the same cells hold records, with the same mean applied rate (record statistics)
    for seq, c in ocells.items():
        assert cells[seq]["n_records"] == c["n_records"]
        if c["mean_applied_rate_kg_ha"] is not None:
            assert cells[seq]["mean_applied_rate_kg_ha"] == pytest.approx(
                c["mean_applied_rate_kg_ha"], abs=0.01
            )
    # eq. 18 accuracy exists where the prescription asks for product and product landed
    assert rep["mean_accuracy_pct"] is not None and rep["applied_total_kg"] > 0


def test_imported_log_machine_is_never_sendable(client, org, driven):  # noqa: F811
    fx, _ = driven
    h = org.headers()
    _, data = _export(client, h, fx.job_id)
    up = {"files": ("TASKDATA.zip", data, "application/zip")}
    url = f"{API}/imports/timelog?prescription_id={fx.prescription_id}&width_m=3"
    sha = client.post(url, headers=h, files=up).json()["sha256"]
    ok = client.post(f"{url}&confirm={sha}", headers=h, files=up)
    assert ok.status_code == 201, ok.text
    pseudo = ok.json()["created"]["machine_id"]
    every = [m["id"] for m in client.get(f"{API}/machines", headers=h).json()["items"]]
    sendable = client.get(f"{API}/machines?sendable=true", headers=h).json()["items"]
    assert pseudo in every and pseudo not in [m["id"] for m in sendable]
    assert sendable  # the real machine of the driven job stays
    r = client.post(
        f"{API}/jobs",
        headers=h,
        json={"prescription_id": fx.prescription_id, "machine_id": pseudo},
    )
    assert r.status_code == 422 and "holds imported logs" in r.json()["detail"]


def test_timelog_archive_is_inflated_outside_the_api_process(client, org, driven):  # noqa: F811
    """A TimeLog zip that inflates to 200 MiB (a filler member of zeros beside the log) was
    inflated in the API process's memory; it is spooled to disk and inflated in the bounded
    worker, so the API's resident memory does not grow by the inflated size."""
    import os
    import threading

    fx, _ = driven
    h = org.headers()
    files, _ = _export(client, h, fx.job_id)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("TLG00001.XML", files["TLG00001.XML"])
        z.writestr("TLG00001.BIN", files["TLG00001.BIN"])
        z.writestr("FILLER.BIN", bytes(200 * 1024 * 1024))
    data = buf.getvalue()
    del buf
    page = os.sysconf("SC_PAGE_SIZE")

    def rss() -> int:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * page

    base = rss()
    peak = [base]
    done = threading.Event()

    def sample() -> None:
        while not done.is_set():
            peak[0] = max(peak[0], rss())
            done.wait(0.005)

    th = threading.Thread(target=sample)
    th.start()
    try:
        r = client.post(
            f"{API}/imports/timelog?prescription_id={fx.prescription_id}",
            headers=h,
            files={"files": ("TASKDATA.zip", data, "application/zip")},
        )
    finally:
        done.set()
        th.join()
    assert r.status_code == 200, r.text
    assert r.json()["timelogs"][0]["records"] > 0
    grew = (peak[0] - base) / 1024**2
    assert grew < 100, f"the API process grew by {grew:.0f} MiB"
