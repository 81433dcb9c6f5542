"""The peer's pool: the 16-section volume-rate sprayer that AgIsoStack++'s task controller
client example uploads (recorded in /work/shared/isobus-peer/t2b_*: 2,329 bytes over ETP;
the trace holds the transfer's frames but not its data bytes, so the pool is rebuilt here
from the example's published layout: a "Sprayer" device element 0 with actual work state,
request default process data (DDI 0xDFFF) and total time; a connector element 1; the
"Boom" function element 2 with offsets, working width as process data (DDI 67, 36,576 mm),
setpoint work state (DDI 289), area total, section control state (DDI 160) and actual /
setpoint condensed work state (DDI 161 / 290); the "Product" bin element 3 with tank
capacity / volume, lifetime volume, prescription control state (DDI 158), setpoint /
actual volume per area (DDI 1 / 2) and the cultural practice; 16 section elements 4-19 on
the boom with offsets and widths; six presentations).

Two deliberate differences from the example, so the replay exercises what a TC must honour:
the example gives its "Request Default PD" object its object id as DDI (here DDI 0xDFFF, as
ISO 11783-10 defines it) and lists the boom's setpoint work state (DDI 289) and area total
in no element (here the boom lists them). Run against the example itself (by hand), it
answers a request for DDI 67 with 0.

Packed byte by byte here (ISO 11783-10 Annex A, version 4 layout), sharing no code with
FieldRx's encoder; ``ddop_strict.decode`` reads it.
"""

from __future__ import annotations

import struct

BOOM_WIDTH_MM = 36_576  # 120 ft
SECTIONS = 16
NAME = 0xA00C8000AFE00002  # the peer client's NAME in the trace


def _t(s: str) -> bytes:
    b = s.encode()
    return bytes((len(b),)) + b


def dvc(oid: int, name: int) -> bytes:
    return (
        b"DVC"
        + struct.pack("<H", oid)
        + _t("AgIsoStack++ UnitTest")
        + _t("1.0.0")
        + name.to_bytes(8, "little")
        + _t("123")
        + b"A++1.0 "
        + bytes((ord("e"), ord("n"), 0x50, 0x00, 0x55, 0x55, 0xFF))
        + b"\x00"
    )


def det(oid: int, kind: int, desig: str, number: int, parent: int, kids: list[int]) -> bytes:
    out = b"DET" + struct.pack("<HB", oid, kind) + _t(desig)
    out += struct.pack("<HHH", number, parent, len(kids))
    return out + b"".join(struct.pack("<H", k) for k in kids)


def dpd(oid: int, ddi: int, props: int, trig: int, desig: str, dvp: int = 0xFFFF) -> bytes:
    return b"DPD" + struct.pack("<HHBB", oid, ddi, props, trig) + _t(desig) + struct.pack("<H", dvp)


def dpt(oid: int, ddi: int, value: int, desig: str, dvp: int = 0xFFFF) -> bytes:
    return b"DPT" + struct.pack("<HHi", oid, ddi, value) + _t(desig) + struct.pack("<H", dvp)


def dvp(oid: int, offset: int, scale: float, decimals: int, unit: str) -> bytes:
    return b"DVP" + struct.pack("<Hif", oid, offset, scale) + bytes((decimals,)) + _t(unit)


DEF, SET = 0x01, 0x02
T_TIME, T_CHANGE, T_TOTAL = 0x01, 0x08, 0x10
# presentations
P_MM, P_M, P_AREA, P_L, P_MIN, P_LHA = 200, 201, 202, 203, 204, 205


def pool(name: int = NAME) -> bytes:
    sw = BOOM_WIDTH_MM // SECTIONS
    out = [dvc(0, name)]
    out.append(det(1, 1, "Sprayer", 0, 0, [2, 3, 4]))
    out += [
        dpd(2, 141, DEF, T_CHANGE, "Actual Work State"),
        dpd(3, 0xDFFF, 0, T_TOTAL, "Request Default PD"),
        dpd(4, 119, DEF | SET, T_TOTAL, "Total Time", P_MIN),
    ]
    out.append(det(5, 6, "Connector", 1, 1, [6, 7, 8]))
    out += [
        dpd(6, 134, SET, 0, "Connector X", P_MM),
        dpd(7, 135, SET, 0, "Connector Y", P_MM),
        dpt(8, 157, 9, "Type"),
    ]
    out.append(det(9, 2, "Boom", 2, 1, list(range(10, 19))))
    out += [
        dpt(10, 134, 0, "Offset X", P_MM),
        dpt(11, 135, 0, "Offset Y", P_MM),
        dpt(12, 136, 0, "Offset Z", P_MM),
        dpd(13, 67, DEF, T_CHANGE, "Actual Working Width", P_M),
        dpd(14, 289, DEF | SET, T_CHANGE, "Setpoint Work State"),
        dpd(15, 116, DEF, T_TOTAL, "Area Total", P_AREA),
        dpd(16, 160, DEF | SET, T_CHANGE | T_TIME, "Section Control State"),
        dpd(17, 161, DEF, T_CHANGE, "Actual Work State 1-16"),
        dpd(18, 290, DEF | SET, T_CHANGE, "Setpoint Work State 1-16"),
    ]
    out.append(det(19, 3, "Product", 3, 9, [20, 21, 22, 23, 24, 25, 26]))
    out += [
        dpd(20, 72, DEF, T_CHANGE | T_TIME, "Tank Capacity", P_L),
        dpd(21, 71, DEF | SET, T_CHANGE | T_TIME, "Tank Volume", P_L),
        dpd(22, 325, DEF, T_TOTAL, "Lifetime Total Volume", P_L),
        dpd(23, 158, DEF | SET, T_CHANGE | T_TIME, "Rx Control State"),
        dpt(24, 179, 3, "Operation Type"),
        dpd(25, 1, DEF | SET, T_CHANGE, "Target Rate", P_LHA),
        dpd(26, 2, DEF, T_CHANGE | T_TIME, "Actual Rate", P_LHA),
    ]
    for i in range(SECTIONS):
        base = 100 + 4 * i
        y = -BOOM_WIDTH_MM // 2 + i * sw + sw // 2
        out.append(det(base, 4, f"Section {i}", 4 + i, 9, [base + 1, base + 2, base + 3]))
        out += [
            dpt(base + 1, 135, y, "Offset Y", P_M),
            dpt(base + 2, 134, -20, "Offset X", P_M),
            dpt(base + 3, 67, sw, "Width", P_M),
        ]
    out += [
        dvp(P_MM, 0, 1.0, 0, "mm"),
        dvp(P_M, 0, 0.001, 0, "m"),
        dvp(P_AREA, 0, 1.0, 0, "m^2"),
        dvp(P_L, 0, 0.001, 0, "L"),
        dvp(P_MIN, 0, 1.0, 1, "minutes"),
        dvp(P_LHA, 0, 0.001, 1, "L/ha"),
    ]
    return b"".join(out)
