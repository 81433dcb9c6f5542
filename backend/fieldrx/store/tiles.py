"""The cell layers of the map as Mapbox vector tiles, straight from PostGIS (ST_AsMVT).

The plan grid, a prescription version's rates and a job's as-applied figures per
cell; the level of detail (overview bins or every cell) is ``services.tiles``'s
choice. Layer ``cells``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from sqlalchemy import text
from sqlalchemy.orm import Session

EXTENT = 4096
BUFFER = 64
BINS = 64
MERC_HALF = 20037508.342789244
EARTH_R = 6378137.0
LAYER = "cells"

_ENV = (
    "env AS (SELECT ST_TileEnvelope(:z, :x, :y) AS e, "
    "ST_Transform(ST_TileEnvelope(:z, :x, :y, margin => :m), 4326) AS e4326)"
)

_MERC_X = f"(((ST_XMin(c.geom) + ST_XMax(c.geom)) / 2) * {MERC_HALF / 180.0!r})"
_MERC_Y = f"(ln(tan(radians(90 + (ST_YMin(c.geom) + ST_YMax(c.geom)) / 2) / 2)) * {EARTH_R!r})"
_BIN = (
    f"floor(({_MERC_X} - ST_XMin(env.e)) / (ST_XMax(env.e) - ST_XMin(env.e)) * {BINS})::int AS bi, "
    f"floor(({_MERC_Y} - ST_YMin(env.e)) / (ST_YMax(env.e) - ST_YMin(env.e)) * {BINS})::int AS bj"
)
_BIN_GEOM = (
    "ST_AsMVTGeom(ST_MakeEnvelope("
    f"ST_XMin(env.e) + bi * (ST_XMax(env.e) - ST_XMin(env.e)) / {BINS}, "
    f"ST_YMin(env.e) + bj * (ST_YMax(env.e) - ST_YMin(env.e)) / {BINS}, "
    f"ST_XMin(env.e) + (bi + 1) * (ST_XMax(env.e) - ST_XMin(env.e)) / {BINS}, "
    f"ST_YMin(env.e) + (bj + 1) * (ST_YMax(env.e) - ST_YMin(env.e)) / {BINS}, 3857), "
    f"env.e, {EXTENT}, 0, false)"
)

PLAN_DETAIL = f"""
WITH {_ENV},
t AS (
  SELECT c.seq, c.swath,
         ST_AsMVTGeom(ST_Transform(c.geom, 3857), env.e, {EXTENT}, {BUFFER}, true) AS geom
  FROM plan_cells c, env
  WHERE c.plan_id = :pid AND c.geom && env.e4326
)
SELECT ST_AsMVT(t.*, '{LAYER}', {EXTENT}, 'geom') FROM t WHERE geom IS NOT NULL
"""

PLAN_OVERVIEW = f"""
WITH {_ENV},
b AS (
  SELECT c.seq, c.swath, {_BIN}
  FROM plan_cells c, env
  WHERE c.plan_id = :pid AND c.geom && env.e4326
    AND c.index_in_swath % :sa = 0 AND c.swath % :sx = 0
),
g AS (
  SELECT min(seq) AS seq, min(swath) AS swath, (count(*) * :sa * :sx)::int AS n_cells, bi, bj
  FROM b WHERE bi BETWEEN 0 AND {BINS - 1} AND bj BETWEEN 0 AND {BINS - 1}
  GROUP BY bi, bj
),
t AS (SELECT seq, swath, n_cells, {_BIN_GEOM} AS geom FROM g, env)
SELECT ST_AsMVT(t.*, '{LAYER}', {EXTENT}, 'geom') FROM t WHERE geom IS NOT NULL
"""

_CLAMPED = "(r.flags && ARRAY['below_meter_range','above_meter_range']::varchar[])"

RX_DETAIL = f"""
WITH {_ENV},
t AS (
  SELECT c.seq, c.swath, r.rate_kg_ha, array_to_string(r.flags, ',') AS flags,
         {_CLAMPED} AS clamped,
         ST_AsMVTGeom(ST_Transform(c.geom, 3857), env.e, {EXTENT}, {BUFFER}, true) AS geom
  FROM plan_cells c JOIN prescription_rates r ON r.version_id = :vid AND r.seq = c.seq, env
  WHERE c.plan_id = :pid AND c.geom && env.e4326
)
SELECT ST_AsMVT(t.*, '{LAYER}', {EXTENT}, 'geom') FROM t WHERE geom IS NOT NULL
"""

RX_OVERVIEW = f"""
WITH {_ENV},
b AS (
  SELECT c.seq, c.swath, c.area_m2, r.rate_kg_ha, array_to_string(r.flags, ',') AS flags,
         {_CLAMPED} AS clamped, {_BIN}
  FROM plan_cells c JOIN prescription_rates r ON r.version_id = :vid AND r.seq = c.seq, env
  WHERE c.plan_id = :pid AND c.geom && env.e4326
    AND c.index_in_swath % :sa = 0 AND c.swath % :sx = 0
),
g AS (
  SELECT min(seq) AS seq, min(swath) AS swath, (count(*) * :sa * :sx)::int AS n_cells,
         round((sum(rate_kg_ha * area_m2) / nullif(sum(area_m2), 0))::numeric, 1)::float8
           AS rate_kg_ha,
         max(flags) AS flags, bool_or(clamped) AS clamped, bi, bj
  FROM b WHERE bi BETWEEN 0 AND {BINS - 1} AND bj BETWEEN 0 AND {BINS - 1}
  GROUP BY bi, bj
),
t AS (SELECT seq, swath, n_cells, coalesce(rate_kg_ha, 0) AS rate_kg_ha, flags, clamped,
             {_BIN_GEOM} AS geom FROM g, env)
SELECT ST_AsMVT(t.*, '{LAYER}', {EXTENT}, 'geom') FROM t WHERE geom IS NOT NULL
"""


def _tile(session: Session, sql: str, z: int, x: int, y: int, **params: object) -> bytes:
    """One MVT of ``sql`` for tile z/x/y (the envelope margin is the tile buffer)."""
    params.update(z=z, x=x, y=y, m=BUFFER / EXTENT)
    return bytes(session.scalar(text(sql), params) or b"")


def cells_tile(
    session: Session,
    plan_id: int,
    version_id: int | None,
    z: int,
    x: int,
    y: int,
    overview: bool,
    stride: tuple[int, int] = (1, 1),
) -> bytes:
    """The plan's grid (``version_id`` None) or a version's rates and flags per cell: every
    cell (detail) or overview bins of sampled cells (area-weighted mean rate per bin)."""
    if version_id is None:
        sql = PLAN_OVERVIEW if overview else PLAN_DETAIL
    else:
        sql = RX_OVERVIEW if overview else RX_DETAIL
    return _tile(session, sql, z, x, y, pid=plan_id, vid=version_id, sa=stride[0], sx=stride[1])


JOB_SQL = f"""
WITH {_ENV},
a AS (
  SELECT * FROM unnest(CAST(:seqs AS int[]), CAST(:target AS float8[]),
                       CAST(:applied AS float8[]), CAST(:acc AS float8[]),
                       CAST(:nrec AS int[]))
      AS a(seq, target_rate, applied_rate, accuracy, n_records)
)
SELECT ST_AsMVT(q, '{LAYER}', {EXTENT}, 'geom') FROM (
  SELECT c.seq, c.swath, coalesce(a.target_rate, 0) AS target_rate,
         coalesce(a.applied_rate, 0) AS applied_rate,
         coalesce(a.n_records, 0) AS n_records, a.accuracy,
         ST_AsMVTGeom(ST_Transform(c.geom, 3857), env.e, {EXTENT}, {BUFFER}, true) AS geom
  FROM env
  JOIN plan_cells c ON c.plan_id = :pid AND c.geom && env.e4326
  LEFT JOIN a ON a.seq = c.seq
) q WHERE q.geom IS NOT NULL
"""


@dataclass(frozen=True)
class JobCellFigures:
    """A job's per-cell figures as columns, one entry per cell ``seq`` (the as-applied
    report's, so map and report show the same numbers)."""

    seq: Sequence[int]
    target_rate: Sequence[float]
    applied_rate: Sequence[float]
    accuracy: Sequence[float | None]
    n_records: Sequence[int]


def job_tile(
    session: Session, plan_id: int, z: int, x: int, y: int, figures: JobCellFigures
) -> bytes:
    """The plan's cells in the tile with a job's per-cell ``figures``."""
    f = figures
    return _tile(
        session, JOB_SQL, z, x, y, pid=plan_id, seqs=list(f.seq), target=list(f.target_rate),
        applied=list(f.applied_rate), acc=list(f.accuracy), nrec=list(f.n_records),
    )  # fmt: skip
