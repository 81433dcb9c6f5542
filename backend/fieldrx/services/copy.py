"""PostgreSQL binary COPY payloads built with numpy: the fast path for large grids.

``psycopg``'s per-row ``write_row`` spends most of its time in Python for
870k-cell plans; here the fixed-width part of every row is one big-endian
numpy structured array and only the variable-length geometry (EWKB) is
interleaved in Python, so a chunk of 100k rows costs a few tens of ms to build.
Format: https://www.postgresql.org/docs/15/sql-copy.html (binary format).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

HEADER = b"PGCOPY\n\xff\r\n\x00" + b"\x00\x00\x00\x00" + b"\x00\x00\x00\x00"
TRAILER = b"\xff\xff"
FLOAT8_OID = 701
TEXT_OID = 25
CHUNK_ROWS = 100_000


def float8_array_fields(n_elems: int) -> list[tuple[str, str]]:
    """Structured-dtype fields of a 1-D float8[] of fixed length (length word included)."""
    fields = [
        ("arr_len", ">i4"),
        ("arr_ndim", ">i4"),
        ("arr_hasnull", ">i4"),
        ("arr_oid", ">u4"),
        ("arr_dim", ">i4"),
        ("arr_lb", ">i4"),
    ]
    for k in range(n_elems):
        fields += [(f"e{k}_len", ">i4"), (f"e{k}", ">f8")]
    return fields


def fill_float8_array(rows: np.ndarray, values: np.ndarray) -> None:
    """Fill the float8[] fields of ``rows`` from an (n, k) array."""
    k = values.shape[1]
    rows["arr_len"] = 20 + 12 * k
    rows["arr_ndim"] = 1
    rows["arr_hasnull"] = 0
    rows["arr_oid"] = FLOAT8_OID
    rows["arr_dim"] = k
    rows["arr_lb"] = 1
    for j in range(k):
        rows[f"e{j}_len"] = 8
        rows[f"e{j}"] = values[:, j]


def interleave(fixed: np.ndarray, tail: Sequence[bytes] | None) -> bytes:
    """Rows = fixed part (+ one variable-length trailing field whose bytes are ``tail``).

    The fixed part must end with the int32 length word of the trailing field.
    """
    data = fixed.tobytes()
    if tail is None:
        return data
    size = fixed.dtype.itemsize
    mv = memoryview(data)
    parts: list[Any] = [None] * (2 * len(tail))
    parts[0::2] = [mv[i * size : (i + 1) * size] for i in range(len(tail))]
    parts[1::2] = tail
    return b"".join(parts)


def chunks(n: int, size: int = CHUNK_ROWS) -> Iterator[slice]:
    for a in range(0, n, size):
        yield slice(a, min(n, a + size))
