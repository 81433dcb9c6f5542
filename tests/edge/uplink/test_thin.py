"""Uplink profile thin on the tractor: the cell records are the as-applied kernel
over the whole 10 Hz log, whatever batches the fixes came in, and a killed agent that
restarts from its raw log neither loses nor repeats a cell record."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest
from fieldrx_edge.asapplied import RecordColumns, records_applied
from fieldrx_edge.cell_records import CellRecord
from fieldrx_edge.gnss.utm import UtmProjection
from fieldrx_edge.metering import calibration_from_dict
from fieldrx_edge.protocol import ProtocolError
from fieldrx_edge.session import load_job
from fieldrx_edge.sim.simulator import SimConfig, simulate
from fieldrx_edge.uplink import TelemetryQueue
from fieldrx_edge.uplink.thin import CellAccumulator, ThinUplink, pack_raw_log


@pytest.fixture(scope="module")
def drive() -> tuple:
    job = load_job("demo:35x23")
    recs: list[dict] = []
    simulate(job, SimConfig(seed=2), sink=lambda b: recs.extend(dict(r) for r in b))
    return job, recs


def _whole_log(job, recs) -> tuple:  # noqa: ANN001
    """What the server's report computes from every fix (fleet.reports.build_report)."""
    acc = CellAccumulator(job)
    proj = UtmProjection(job.utm_epsg)
    xy = np.array([proj.forward(r["lon"], r["lat"]) for r in recs])
    idx = {int(s): i for i, s in enumerate(job.seq)}
    own = np.array([-1 if r["cell_seq"] is None else idx.get(r["cell_seq"], -1) for r in recs])

    def col(k: str, d: float = np.nan) -> np.ndarray:
        return np.array([d if r.get(k) is None else r[k] for r in recs], dtype=float)

    v = col("speed_filtered_m_s", 0.0)
    cols = RecordColumns(
        col("t"), col("fix_period_s"), xy[:, 0], xy[:, 1], col("heading_deg", 0.0),
        col("actual_shaft_rpm"), own,
        col("applied_rate_kg_ha", 0.0) * job.implement_width_m * v * 6 / 60,
    )  # fmt: skip
    res = records_applied(
        acc.cells, cols, calibration_from_dict(job.calibration), job.lag_s, job.antenna_forward_m
    )
    down = np.array([r["implement_down"] for r in recs])
    return res, own, down, idx


def _sum(cells: list[dict], idx: dict, n: int) -> tuple:
    m2, nf = np.zeros(n), np.zeros(n, dtype=int)
    outside = worked = 0.0
    for c in cells:
        CellRecord.from_dict({**c, "machine_id": 1, "seq": 1})  # each follows the protocol
        worked += c["worked_s"]
        if c["cell_seq"] is None:
            outside += c["mass_g"]
        else:
            m2[idx[c["cell_seq"]]] += c["mass_g"]
            nf[idx[c["cell_seq"]]] += c["n_fixes"]
    return m2, nf, outside, worked


@pytest.mark.parametrize("batch", [1, 7, 200])
def test_cell_records_are_the_kernel_over_the_whole_log(drive, batch: int) -> None:  # noqa: ANN001
    job, recs = drive
    res, own, down, idx = _whole_log(job, recs)
    acc = CellAccumulator(job)
    out: list[dict] = []
    for i in range(0, len(recs), batch):
        for r in recs[i : i + batch]:
            out.extend(acc.add(dict(r)))
    out.extend(acc.flush())
    m2, nf, outside, worked = _sum(out, idx, job.n_cells)
    np.testing.assert_allclose(m2, res.m2_g, rtol=1e-9, atol=1e-9)
    assert outside == pytest.approx(res.outside_g, rel=1e-9)
    assert worked == pytest.approx(float(res.dts[down].sum()), rel=1e-9)
    assert (nf == np.bincount(own[(own >= 0) & down], minlength=job.n_cells)).all()
    # about one record per cell worked, not one per fix
    worked_cells = int((nf > 0).sum())
    assert worked_cells <= len(out) < 2 * worked_cells + 5


def test_restart_from_raw_log_loses_and_repeats_nothing(drive, tmp_path: Path) -> None:  # noqa: ANN001
    job, recs = drive
    res, _, _, idx = _whole_log(job, recs)

    def uplink() -> ThinUplink:
        track = TelemetryQueue(tmp_path / "queue.sqlite", job.machine_id)
        cells = TelemetryQueue(tmp_path / "cells.sqlite", job.machine_id, kind="cells")
        return ThinUplink(job, track, cells, tmp_path / "raw" / "job.jsonl")

    first = uplink()
    cut = len(recs) // 2
    first.put_many([dict(r) for r in recs[:cut]])
    before = first.cells.last_seq
    # a kill after the raw log was written but before the cell records were queued: the
    # last line of the log is there, its cell records are not
    first.raw.write([dict(recs[cut])])
    del first
    second = uplink()
    second.put_many([dict(r) for r in recs[cut + 1 :]])
    second.flush()
    q = second.cells
    assert q.last_seq > before
    body = json.loads(q.pending_batch(100_000)[0])
    assert body["kind"] == "cells" and body["format"] == 3
    m2, _, outside, _ = _sum(body["records"], idx, job.n_cells)
    np.testing.assert_allclose(m2, res.m2_g, rtol=1e-9, atol=1e-9)
    assert outside == pytest.approx(res.outside_g, rel=1e-9)
    assert [r["seq"] for r in body["records"]] == list(range(1, q.last_seq + 1))
    # the track: about one record per second, without cells (the cell records count them)
    track = second.track.pending(100_000)
    span = recs[-1]["t"] - recs[0]["t"]
    assert span * 0.9 < len(track) < span * 1.1 + 2
    assert all(r["cell_seq"] is None for r in track)
    # the whole 10 Hz log stays on the tractor, one gzip file per job to upload
    lines = gzip.decompress(pack_raw_log(second.raw.path)).decode().splitlines()
    assert len(lines) == len(recs)


def test_cell_record_validation_names_the_field() -> None:
    ok = {"machine_id": 1, "seq": 1, "job_id": 2, "t_entry": 1e9, "t_exit": 1e9 + 1}
    CellRecord.from_dict(ok)
    for bad, word in (
        ({"mass_g": -1.0}, "mass_g"),
        ({"t_exit": 1e9 - 1}, "t_exit"),
        ({"flags": ["nope"]}, "flags"),
        ({"cell_seq": 1.5}, "cell_seq"),
        ({"extra": 1}, "extra"),
    ):
        with pytest.raises(ProtocolError, match=word):
            CellRecord.from_dict({**ok, **bad})
