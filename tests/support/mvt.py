"""A minimal Mapbox Vector Tile (protobuf) reader for tests: layers, keys, values, features.

mapbox-vector-tile is not a dependency; the MVT 2.1 wire format is small enough to walk
here (Tile.layers = 3; Layer: name 1, features 2, keys 3, values 4, extent 5, version 15;
Feature: id 1, tags 2, type 3, geometry 4; Value: string 1, float 2, double 3, int 4,
uint 5, sint 6, bool 7).
"""

from __future__ import annotations

import struct
from typing import Any


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    shift = result = 0
    while True:
        b = buf[i]
        i += 1
        result |= (b & 0x7F) << shift
        if not b & 0x80:
            return result, i
        shift += 7


def _fields(buf: bytes) -> list[tuple[int, int, Any]]:
    out, i = [], 0
    while i < len(buf):
        key, i = _varint(buf, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = _varint(buf, i)
        elif wt == 1:
            v, i = buf[i : i + 8], i + 8
        elif wt == 2:
            n, i = _varint(buf, i)
            v, i = buf[i : i + n], i + n
        elif wt == 5:
            v, i = buf[i : i + 4], i + 4
        else:
            raise ValueError(f"unsupported wire type {wt}")
        out.append((num, wt, v))
    return out


def _packed(buf: bytes) -> list[int]:
    vals, i = [], 0
    while i < len(buf):
        v, i = _varint(buf, i)
        vals.append(v)
    return vals


def _value(buf: bytes) -> Any:
    for num, _, v in _fields(buf):
        if num == 1:
            return v.decode()
        if num == 2:
            return struct.unpack("<f", v)[0]
        if num == 3:
            return struct.unpack("<d", v)[0]
        if num in (4, 5):
            return v if v < 1 << 63 else v - (1 << 64)
        if num == 6:
            return (v >> 1) ^ -(v & 1)
        if num == 7:
            return bool(v)
    return None


def _rings(geom: list[int]) -> list[list[tuple[int, int]]]:
    """Decode polygon geometry commands into rings of tile coordinates."""
    rings: list[list[tuple[int, int]]] = []
    x = y = i = 0
    cur: list[tuple[int, int]] = []
    while i < len(geom):
        cmd, count = geom[i] & 7, geom[i] >> 3
        i += 1
        if cmd == 7:  # ClosePath
            rings.append(cur)
            cur = []
            continue
        for _ in range(count):
            dx, dy = geom[i], geom[i + 1]
            i += 2
            x += (dx >> 1) ^ -(dx & 1)
            y += (dy >> 1) ^ -(dy & 1)
            if cmd == 1:
                cur = [(x, y)]
            else:
                cur.append((x, y))
    return rings


def decode(tile: bytes) -> dict[str, dict[str, Any]]:
    """{layer name: {"extent", "version", "features": [{"type", "properties", "rings"}]}}."""
    layers: dict[str, dict[str, Any]] = {}
    for num, _, lbuf in _fields(tile):
        if num != 3:
            continue
        name, keys, values, raw, extent, version = "", [], [], [], 4096, 1
        for n, _, v in _fields(lbuf):
            if n == 1:
                name = v.decode()
            elif n == 2:
                raw.append(v)
            elif n == 3:
                keys.append(v.decode())
            elif n == 4:
                values.append(_value(v))
            elif n == 5:
                extent = v
            elif n == 15:
                version = v
        feats = []
        for fbuf in raw:
            tags: list[int] = []
            geom: list[int] = []
            gtype = 0
            for n, _, v in _fields(fbuf):
                if n == 2:
                    tags = _packed(v)
                elif n == 3:
                    gtype = v
                elif n == 4:
                    geom = _packed(v)
            props = {keys[tags[k]]: values[tags[k + 1]] for k in range(0, len(tags), 2)}
            feats.append({"type": gtype, "properties": props, "rings": _rings(geom)})
        layers[name] = {"extent": extent, "version": version, "features": feats}
    return layers


def lonlat_to_tile(lon: float, lat: float, z: int) -> tuple[int, int]:
    import math

    n = 1 << z
    x = int((lon + 180.0) / 360.0 * n)
    y = int((1.0 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2.0 * n)
    return x, y
