"""A strict, independent reader of ISO 11783-10 binary device descriptor object pools, for
checking the pools FieldRx writes (it shares no code with ``fieldrx_edge.isobus.ddop``).

Written from the standard's object tables (ISO 11783-10:2015 Annex A: A.2 DVC, A.3 DET,
A.4 DPD, A.5 DPT, A.6 DVP; Annex B.1 binary format) as also implemented by AgIsoStack++
(``DeviceDescriptorObjectPool::deserialize_binary_object_pool`` and
``task_controller_object::*::get_binary_object``):

* DVC: id, designator, software version, NAME (8), serial number, structure label (7),
  localization label (7); at TC version 4 and later one more byte, the extended structure
  label's length (always present, 0 without a label), then the label (<= 32 bytes).
* DET: id, type (1..7), designator, element number (<= 4095), parent id, number of objects
  to follow, their ids; those objects are the element's DPD and DPT objects.
* DPD: id, DDI, properties (bits 0-2), trigger methods (bits 0-4), designator, DVP id.
* DPT: id, DDI, int32 value, designator, DVP id.   DVP: id, int32 offset, float32 scale,
  decimals, unit designator.

Pool rules: one DVC, object id 0; one device element (type 1) whose parent is the DVC;
other elements' parents are elements leading to it; ids unique; references resolve.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field


class StrictDdopError(ValueError):
    pass


@dataclass
class Pool:
    version: int
    objects: dict[int, tuple[str, dict]] = field(default_factory=dict)
    order: list[int] = field(default_factory=list)

    def of_type(self, tag: str) -> list[tuple[int, dict]]:
        return [(i, self.objects[i][1]) for i in self.order if self.objects[i][0] == tag]


class _Cursor:
    def __init__(self, raw: bytes, version: int) -> None:
        self.raw, self.pos = raw, 0
        self.max_text = 32 if version < 4 else 128

    def bytes_(self, n: int, what: str) -> bytes:
        if n < 0 or self.pos + n > len(self.raw):
            raise StrictDdopError(f"{what}: needs {n} bytes at offset {self.pos}")
        out = self.raw[self.pos : self.pos + n]
        self.pos += n
        return out

    def uint(self, n: int, what: str) -> int:
        return int.from_bytes(self.bytes_(n, what), "little")

    def sint32(self, what: str) -> int:
        return int.from_bytes(self.bytes_(4, what), "little", signed=True)

    def string(self, what: str) -> bytes:
        n = self.uint(1, what + " length")
        if n > self.max_text:
            raise StrictDdopError(f"{what}: {n} bytes, at most {self.max_text}")
        return self.bytes_(n, what)


def _dvc(c: _Cursor, version: int) -> dict:
    o = {
        "designator": c.string("DVC designator"),
        "software": c.string("DVC software version"),
        "name": c.bytes_(8, "DVC NAME"),
        "serial": c.string("DVC serial number"),
        "structure": c.bytes_(7, "DVC structure label"),
        "localization": c.bytes_(7, "DVC localization label"),
        "ext": b"",
    }
    if version >= 4:
        n = c.uint(1, "DVC extended structure label length")
        if n > 32:
            raise StrictDdopError(f"DVC extended structure label of {n} bytes")
        o["ext"] = c.bytes_(n, "DVC extended structure label")
    return o


def _det(c: _Cursor) -> dict:
    kind = c.uint(1, "DET type")
    desig = c.string("DET designator")
    number, parent, n = c.uint(2, "DET number"), c.uint(2, "DET parent"), c.uint(2, "DET count")
    kids = [c.uint(2, "DET child") for _ in range(n)]
    return {"type": kind, "designator": desig, "number": number, "parent": parent, "kids": kids}


def _dpd(c: _Cursor) -> dict:
    ddi, props, trig = c.uint(2, "DPD DDI"), c.uint(1, "DPD props"), c.uint(1, "DPD triggers")
    if props & 0xF8 or trig & 0xE0:
        raise StrictDdopError(f"DPD reserved bits set: props 0x{props:02X} triggers 0x{trig:02X}")
    desig = c.string("DPD designator")
    return {
        "ddi": ddi,
        "props": props,
        "triggers": trig,
        "designator": desig,
        "dvp": c.uint(2, "DPD DVP"),
    }


def _dpt(c: _Cursor) -> dict:
    ddi, value = c.uint(2, "DPT DDI"), c.sint32("DPT value")
    desig = c.string("DPT designator")
    return {"ddi": ddi, "value": value, "designator": desig, "dvp": c.uint(2, "DPT DVP")}


def _dvp(c: _Cursor) -> dict:
    offset = c.sint32("DVP offset")
    scale = struct.unpack("<f", c.bytes_(4, "DVP scale"))[0]
    return {
        "offset": offset,
        "scale": scale,
        "decimals": c.uint(1, "DVP decimals"),
        "unit": c.string("DVP unit"),
    }


def decode(raw: bytes, version: int = 4) -> Pool:
    """Read and check a whole pool; ``StrictDdopError`` on the first violation."""
    c = _Cursor(bytes(raw), version)
    pool = Pool(version)
    while c.pos < len(c.raw):
        tag = c.bytes_(3, "object table id").decode("ascii", "replace")
        oid = c.uint(2, f"{tag} object id")
        if oid in pool.objects or oid == 0xFFFF:
            raise StrictDdopError(f"object id {oid} repeated or reserved")
        readers = {
            "DVC": lambda: _dvc(c, version),
            "DET": lambda: _det(c),
            "DPD": lambda: _dpd(c),
            "DPT": lambda: _dpt(c),
            "DVP": lambda: _dvp(c),
        }
        if tag not in readers:
            raise StrictDdopError(f"unknown table id {tag!r} at offset {c.pos - 5}")
        pool.objects[oid] = (tag, readers[tag]())
        pool.order.append(oid)
    _check(pool)
    return pool


def _check(pool: Pool) -> None:
    dvcs = pool.of_type("DVC")
    if len(dvcs) != 1 or dvcs[0][0] != 0:
        raise StrictDdopError(f"need one DVC with object id 0, got {[i for i, _ in dvcs]}")
    dets = dict(pool.of_type("DET"))
    devices = [i for i, d in dets.items() if d["type"] == 1]
    if len(devices) != 1 or dets[devices[0]]["parent"] != 0:
        raise StrictDdopError("need exactly one device element (type 1) whose parent is 0")
    numbers = [d["number"] for d in dets.values()]
    if len(set(numbers)) != len(numbers) or max(numbers) > 4095:
        raise StrictDdopError("element numbers repeated or above 4095")
    for i, d in dets.items():
        if not 1 <= d["type"] <= 7:
            raise StrictDdopError(f"DET {i}: type {d['type']}")
        for k in d["kids"]:
            if k not in pool.objects or pool.objects[k][0] not in ("DPD", "DPT"):
                raise StrictDdopError(f"DET {i}: object {k} is not one of its DPD/DPT objects")
        if d["type"] != 1:
            hops, p = 0, d["parent"]
            while p in dets and dets[p]["type"] != 1 and hops <= len(dets):
                p, hops = dets[p]["parent"], hops + 1
            if p not in dets or hops > len(dets):
                raise StrictDdopError(f"DET {i}: parent chain does not reach the device element")
    for i in pool.order:
        tag, o = pool.objects[i]
        if tag in ("DPD", "DPT") and o["dvp"] != 0xFFFF:
            if pool.objects.get(o["dvp"], ("", {}))[0] != "DVP":
                raise StrictDdopError(f"{tag} {i}: DVP {o['dvp']} missing")
