"""The one binary COPY codec: row layouts, arrays, NULLs, packed reads, through real PostgreSQL."""

from __future__ import annotations

import numpy as np
import pytest
from fieldrx.store import codec
from fieldrx.store.cells import driver_connection


def test_row_dtype_lays_out_length_words_and_values() -> None:
    dt = codec.row_dtype([("a", "int4"), ("b", "float8"), ("c", "float8[2]")], tail=True)
    assert dt.names[:5] == ("nf", "l_a", "a", "l_b", "b")
    assert dt.names[-1] == "l_tail"
    # 2 + (4+4) + (4+8) + (4 + 20 + 2 * 12) + 4
    assert dt.itemsize == 2 + 8 + 12 + 48 + 4
    rows = codec.new_rows(dt, 2, 3)
    assert rows["nf"].tolist() == [3, 3]
    assert rows["l_a"].tolist() == [4, 4] and rows["l_b"].tolist() == [8, 8]
    assert rows.tobytes()[:6] == b"\x00\x03\x00\x00\x00\x04"  # big-endian on the wire


def test_copy_spec_refuses_mismatched_types() -> None:
    with pytest.raises(ValueError, match="2 columns, 1 types"):
        codec.CopySpec("t", ("a", "b"), ("int4",))


def test_varchar_array_empty_and_full() -> None:
    assert (
        codec.varchar_array([]) == b"\x00\x00\x00\x00" + b"\x00\x00\x00\x00" + b"\x00\x00\x04\x13"
    )
    b = codec.varchar_array(["ab", "c"])
    assert b.endswith(b"\x00\x00\x00\x02ab\x00\x00\x00\x01c")


def test_round_trip_through_postgresql(db) -> None:
    """Numpy rows (with a NULL, a float8[] and a varchar[] tail) COPY in and read back
    packed; the declared-type row path writes the same table."""
    conn = driver_connection(db)
    n = 250_001  # crosses a chunk boundary of the payload below
    spec = codec.CopySpec(
        "codec_t", ("i", "f", "arr", "tags"), ("int4", "float8", "float8[3]", "varchar[]")
    )
    i = np.arange(n, dtype=np.int64) - 5
    f = np.linspace(-1e6, 1e6, n)
    arr = np.stack([f, f * 2, -f], axis=1)
    tags = codec.varchar_array(["x", "yz"])
    with conn.cursor() as cur:
        cur.execute("CREATE TEMP TABLE codec_t (i int, f float8, arr float8[], tags varchar[])")

        tail = [("l_tags", ">i4"), ("tags", f"V{len(tags)}")]
        full = np.dtype(
            codec.row_dtype([("i", "int4"), ("f", "float8"), ("arr", "float8[3]")]).descr + tail
        )
        # a NULL f: the length word -1 and no value bytes
        null = np.dtype(
            codec.row_dtype([("i", "int4")]).descr
            + [("l_f", ">i4")]
            + codec.float8_array_fields(3, "arr")
            + tail
        )

        def fill(rows: np.ndarray, sl: slice) -> np.ndarray:
            rows["i"] = i[sl]
            if "f" in rows.dtype.names:
                rows["f"] = f[sl]
            else:
                rows["l_f"] = codec.NULL
            codec.fill_float8_array(rows, arr[sl], "arr")
            rows["tags"] = np.frombuffer(tags, dtype=f"V{len(tags)}")[0]
            return rows

        def payload():  # noqa: ANN202
            yield codec.HEADER
            yield fill(codec.new_rows(null, 1, 4), slice(0, 1)).tobytes()
            for sl in codec.chunks(n - 1):
                s1 = slice(sl.start + 1, sl.stop + 1)
                yield fill(codec.new_rows(full, s1.stop - s1.start, 4), s1).tobytes()
            yield codec.TRAILER

        spec.write_payload(cur, payload())
        spec.write_rows(cur, [(n + 10, 0.5, [1.0, 2.0, 3.0], ["w"])])
    with conn.cursor(binary=True) as cur:
        cur.execute(
            codec.packed_select(
                [("i", "int4"), ("coalesce(f, 'NaN')", "float8"), ("arr", "float8[3]")],
                "SELECT * FROM codec_t ORDER BY i",
            )
        )
        row = cur.fetchone()
    assert row[-1] == n + 1
    gi = codec.unpack(bytes(row[0]), "int4")
    gf = codec.unpack(bytes(row[1]), "float8")
    ga = codec.unpack(bytes(row[2]), "float8[3]").reshape(-1, 3)
    assert gi.tolist() == np.r_[i, n + 10].tolist()
    k7 = n  # the declared-type row, last
    assert np.isnan(gf[0]) and gf[k7] == 0.5
    np.testing.assert_array_equal(gf[1:n], f[1:])
    np.testing.assert_array_equal(ga[0], arr[0])
    assert ga[k7].tolist() == [1.0, 2.0, 3.0]
    tags_back = db.connection().exec_driver_sql("SELECT DISTINCT tags FROM codec_t").all()
    assert sorted(t[0] for t in tags_back) == [["w"], ["x", "yz"]]
    db.rollback()
