"""The telemetry COPY columns are stated once (fleet.telemetry_row) and match the table."""

from __future__ import annotations

from fieldrx.fleet.ingest.validate import validate
from fieldrx.fleet.telemetry_row import TELEMETRY_COPY, TelemetryRow
from fieldrx_edge.protocol import EXTRA_FIELDS, TELEMETRY_FIELDS
from sqlalchemy import text


def test_columns_exist_in_the_table_with_their_types(db) -> None:
    rows = db.execute(
        text(
            "SELECT column_name, udt_name FROM information_schema.columns"
            " WHERE table_name = 'telemetry'"
        )
    ).all()
    udt = dict(rows)
    want = {"int4": "int4", "int8": "int8", "int2": "int2", "float8": "float8", "bool": "bool",
            "varchar": "varchar", "varchar[]": "_varchar", "bytea": "geometry"}  # fmt: skip
    for col, typ in zip(TELEMETRY_COPY.columns, TELEMETRY_COPY.types, strict=True):
        if col == "t":
            assert udt[col] == "timestamptz"  # sent as int8 microseconds since 2000
        else:
            assert udt[col] == want[typ], col


def test_every_record_field_has_its_column() -> None:
    cols = set(TelemetryRow._fields)
    # lon/lat travel as one EWKB point; every other record field is a column of its own
    assert set(TELEMETRY_FIELDS) - {"lon", "lat"} <= cols
    assert set(EXTRA_FIELDS) <= cols


def test_validated_records_are_typed_rows() -> None:
    rec = {f: None for f in TELEMETRY_FIELDS}
    rec.update(machine_id=3, seq=1, t=1.7e9, lon=11.0, lat=48.0, fix_quality=4, alarms=[])
    rec.update(implement_down=True, queue_backlog=0, speed_raw_m_s=2.0, fix_period_s=0.1)
    rows, rejected, _, _ = validate([rec, dict(rec, seq=2, speed_filtered_m_s=1.5)], 3)
    assert not rejected
    r1, r2 = rows[1], rows[2]
    assert isinstance(r1, TelemetryRow)
    assert r1.speed_m_s == 2.0 and r2.speed_m_s == 1.5  # filtered first, raw as fallback
    assert r1.lonlat == (11.0, 48.0) and abs(r1.t_s - 1.7e9) < 1e-6
    assert r1.gain_kd is None
