"""A prescription version's per-cell rates in ``prescription_rates`` (binary COPY, packed read).

Version n's rates live under that version's id; an edit writes a whole new rate
set (n+1) and never touches n. Flags are stored as the names of the set bits
(``agronomy.cells.FLAG_BITS``) and come back as the bit mask.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import FLAG_BITS, flag_names
from fieldrx.store import codec
from fieldrx.store.cells import driver_connection

RATES = codec.CopySpec(
    "prescription_rates",
    ("version_id", "seq", "rate_kg_ha", "source_value", "flags"),
    ("int4", "int4", "float8", "float8", "varchar[]"),
)


def write_rates(
    session: Session,
    version_id: int,
    seq: np.ndarray,
    rate_kg_ha: np.ndarray,
    flags: np.ndarray,
    source_value: np.ndarray | None,
) -> None:
    """All rates of one version with one binary COPY (in the session's transaction).

    Rows are grouped by (flag mask, source present): within a group every row has
    the same layout, so each group is one numpy structured array. NaN source values
    are stored as NULL (no data).
    """
    n = len(seq)
    rate = np.asarray(rate_kg_ha, dtype=float)
    if len(rate) != n or len(flags) != n:
        raise ValueError(f"rates: {len(rate)} rates and {len(flags)} flags for {n} cells")
    if not np.isfinite(rate).all():
        i = int(np.flatnonzero(~np.isfinite(rate))[0])
        raise ValueError(f"rates: cell seq {int(seq[i])} has no finite rate ({rate[i]})")
    src = np.full(n, np.nan) if source_value is None else np.asarray(source_value, float)
    has_src = ~np.isnan(src)
    key = np.asarray(flags, np.int64) * 2 + has_src
    seq = np.asarray(seq)
    conn = driver_connection(session)

    def payload() -> Any:
        yield codec.HEADER
        for k in np.unique(key):
            rows = np.flatnonzero(key == k)
            fl = codec.varchar_array(flag_names(int(k) // 2))
            cols = [("version_id", "int4"), ("seq", "int4"), ("rate_kg_ha", "float8")]
            if k % 2:
                cols.append(("source_value", "float8"))
            null_src = [] if k % 2 else [("l_source_value", ">i4")]  # a length word only
            dt = np.dtype(
                codec.row_dtype(cols).descr
                + null_src
                + [("l_flags", ">i4"), ("flags", f"V{len(fl)}")]
            )
            a = codec.new_rows(dt, len(rows), len(RATES.columns))
            a["version_id"] = version_id
            a["seq"] = seq[rows]
            a["rate_kg_ha"] = rate[rows]
            if k % 2:
                a["source_value"] = src[rows]
            else:
                a["l_source_value"] = codec.NULL
            a["l_flags"] = len(fl)
            a["flags"] = np.frombuffer(fl, dtype=f"V{len(fl)}")[0]
            yield a.tobytes()
        yield codec.TRAILER

    with conn.cursor() as cur:
        RATES.write_payload(cur, payload())


_MASK_SQL = " | ".join(
    f"(CASE WHEN '{name}' = ANY(flags) THEN {bit} ELSE 0 END)" for name, bit in FLAG_BITS.items()
)
_RATE_COLUMNS = [
    ("seq", "int4"),
    ("rate_kg_ha", "float8"),
    ("coalesce(source_value, 'NaN'::float8)", "float8"),
    (_MASK_SQL, "int4"),
]
_RATES_SQL = codec.packed_select(
    _RATE_COLUMNS,
    "SELECT * FROM prescription_rates WHERE version_id = %s AND seq >= %s AND seq < %s"
    " ORDER BY seq",
)
INT4_MAX = 2**31 - 1


def load_rates(
    session: Session, version_id: int, lo: int = 0, hi: int = INT4_MAX
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(seq, rate_kg_ha, flag bits, source_value) of one version's cells lo <= seq < hi
    (default all) in path order (packed fetch); NaN source value: none stored."""
    conn = driver_connection(session)
    with conn.cursor(binary=True) as cur:
        cur.execute(_RATES_SQL, (version_id, lo, hi))
        row = cur.fetchone()
    if row is None or not row[-1]:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.uint16), np.zeros(0)
    seq, rate, src, masks = (
        codec.unpack(bytes(row[j]), typ) for j, (_, typ) in enumerate(_RATE_COLUMNS)
    )
    seq = seq.astype(np.int64)
    masks = masks.astype(np.uint16)
    order = np.argsort(seq, kind="stable")
    if not np.array_equal(order, np.arange(len(seq))):
        seq, rate, src, masks = seq[order], rate[order], src[order], masks[order]
    return seq, rate, masks, src
