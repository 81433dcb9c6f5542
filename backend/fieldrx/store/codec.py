"""The one PostgreSQL binary COPY codec (and the packed reads that mirror it).

Writing: psycopg's per-row ``write_row`` spends most of its time in Python for
870k-cell plans, so fixed-width columns are laid out as one big-endian numpy
structured array per chunk (``row_dtype`` + the ``fill_*`` helpers) and only a
variable-length trailing field (EWKB) is interleaved in Python; a chunk of 100k
rows costs a few tens of ms. Row-shaped data that arrives one record at a time
(telemetry) goes through :class:`CopySpec.write_rows` with the column types
declared once (psycopg's C row encoder). Format:
https://www.postgresql.org/docs/15/sql-copy.html (binary format).

Reading: ``packed_select`` aggregates each column of a range of rows into one
bytea in its binary wire form (``int4send`` / ``float8send`` ...), so 870k rows
cross the wire as a handful of values; ``unpack`` cuts them up with numpy.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

HEADER = b"PGCOPY\n\xff\r\n\x00" + b"\x00\x00\x00\x00" + b"\x00\x00\x00\x00"
TRAILER = b"\xff\xff"
FLOAT8_OID = 701
TEXT_OID = 25
VARCHAR_OID = 1043
CHUNK_ROWS = 100_000
NULL = -1  # the length word of a NULL field

# fixed-width binary forms: COPY type -> (numpy big-endian dtype, byte width, send function)
FIXED: dict[str, tuple[str, int, str]] = {
    "int2": (">i2", 2, "int2send"),
    "int4": (">i4", 4, "int4send"),
    "int8": (">i8", 8, "int8send"),
    "float8": (">f8", 8, "float8send"),
}


def row_dtype(columns: Sequence[tuple[str, str]], tail: bool = False) -> np.dtype:
    """Structured dtype of one binary COPY row of fixed-width ``(name, COPY type)``
    columns: field count, then a length word ``l_<name>`` and the value per column.

    ``float8[k]`` is a 1-D float8 array of fixed length k. With ``tail`` the row ends
    with the length word ``l_tail`` of one variable-length last field (``interleave``).
    """
    fields: list[tuple[str, Any]] = [("nf", ">i2")]
    for name, typ in columns:
        if typ.startswith("float8[") and typ.endswith("]"):
            fields += float8_array_fields(int(typ[7:-1]), name)
        else:
            fields += [(f"l_{name}", ">i4"), (name, FIXED[typ][0])]
    if tail:
        fields.append(("l_tail", ">i4"))
    return np.dtype(fields)


def new_rows(dtype: np.dtype, n: int, n_fields: int) -> np.ndarray:
    """n zeroed rows with the field count and every fixed length word set."""
    rows = np.zeros(n, dtype=dtype)
    rows["nf"] = n_fields
    names = dtype.names or ()
    fields: Mapping[str, Any] = dtype.fields or {}
    for name in names:
        if name.startswith("l_") and name != "l_tail" and name[2:] in names:
            rows[name] = fields[name[2:]][0].itemsize
    return rows


def float8_array_fields(n_elems: int, name: str = "arr") -> list[tuple[str, str]]:
    """Structured-dtype fields of a 1-D float8[] of fixed length (length word included)."""
    fields = [
        (f"l_{name}", ">i4"),
        (f"{name}_ndim", ">i4"),
        (f"{name}_hasnull", ">i4"),
        (f"{name}_oid", ">u4"),
        (f"{name}_dim", ">i4"),
        (f"{name}_lb", ">i4"),
    ]
    for k in range(n_elems):
        fields += [(f"{name}_e{k}_len", ">i4"), (f"{name}_e{k}", ">f8")]
    return fields


def fill_float8_array(rows: np.ndarray, values: np.ndarray, name: str = "arr") -> None:
    """Fill the float8[] fields ``name`` of ``rows`` from an (n, k) array."""
    k = values.shape[1]
    rows[f"l_{name}"] = 20 + 12 * k
    rows[f"{name}_ndim"] = 1
    rows[f"{name}_hasnull"] = 0
    rows[f"{name}_oid"] = FLOAT8_OID
    rows[f"{name}_dim"] = k
    rows[f"{name}_lb"] = 1
    for j in range(k):
        rows[f"{name}_e{j}_len"] = 8
        rows[f"{name}_e{j}"] = values[:, j]


def varchar_array(items: Sequence[str]) -> bytes:
    """Binary form of a 1-D varchar[] (an empty array has no dimensions)."""
    names = [n.encode() for n in items]
    if not names:
        return struct.pack(">iiI", 0, 0, VARCHAR_OID)
    body = struct.pack(">iiIii", 1, 0, VARCHAR_OID, len(names), 1)
    return body + b"".join(struct.pack(">i", len(b)) + b for b in names)


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


def _psycopg_type(typ: str) -> str:
    """psycopg's name of a COPY type (fixed-length arrays are plain arrays to it)."""
    return typ[: typ.index("[")] + "[]" if "[" in typ else typ


@dataclass(frozen=True)
class CopySpec:
    """A table's COPY column list and binary types, stated once."""

    table: str
    columns: tuple[str, ...]
    types: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.columns) != len(self.types):
            raise ValueError(
                f"COPY {self.table}: {len(self.columns)} columns, {len(self.types)} types"
            )

    def sql(self, table: str | None = None) -> str:
        return f"COPY {table or self.table} ({', '.join(self.columns)}) FROM STDIN (FORMAT BINARY)"

    def write_rows(self, cur: Any, rows: Iterable[Sequence[Any]], table: str | None = None) -> int:
        """COPY row tuples (in column order) with psycopg's binary row encoder."""
        n = 0
        with cur.copy(self.sql(table)) as cp:
            cp.set_types([_psycopg_type(t) for t in self.types])
            write = cp.write_row
            for r in rows:
                write(r)
                n += 1
        return n

    def write_payload(self, cur: Any, payload: Iterable[bytes], table: str | None = None) -> None:
        """COPY a ready binary payload (HEADER, rows, TRAILER), streamed chunk by chunk."""
        with cur.copy(self.sql(table)) as cp:
            for chunk in payload:
                cp.write(chunk)


def packed_select(columns: Sequence[tuple[str, str]], source_sql: str) -> str:
    """SELECT of one row: each ``(expression, COPY type)`` of ``source_sql``'s rows
    aggregated into one bytea of binary values, plus the row count last. Types are
    ``FIXED`` ones, ``bytea`` (values concatenated; send their lengths as an int4
    column) or ``float8[k]`` (fixed-length arrays)."""
    aggs = []
    for expr, typ in columns:
        if typ == "bytea":
            aggs.append(f"string_agg({expr}, ''::bytea)")
        elif typ.startswith("float8["):
            aggs.append(f"string_agg(array_send({expr}), ''::bytea)")
        else:
            aggs.append(f"string_agg({FIXED[typ][2]}({expr}), ''::bytea)")
    return f"SELECT {', '.join(aggs)}, count(*) FROM ({source_sql}) s"


def unpack(data: bytes | None, typ: str) -> np.ndarray:
    """One ``packed_select`` column back as a numpy array (native byte order)."""
    if typ == "bytea":
        return np.frombuffer(data or b"", np.uint8)
    if typ.startswith("float8["):
        k = int(typ[7:-1])
        dt = np.dtype([("hdr", "V20"), ("v", [("l", ">i4"), ("x", ">f8")], (k,))])
        return np.frombuffer(data or b"", dt)["v"]["x"].astype(float)
    return np.frombuffer(data or b"", FIXED[typ][0]).astype(FIXED[typ][0].replace(">", "="))
