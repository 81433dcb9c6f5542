"""Stage: boustrophedon decomposition, done on the swaths themselves.

Swaths of consecutive strips that touch are linked when the link is unique (one swath
above, one below); maximal chains are the monotone blocks (cells) of Choset's
decomposition, split at the critical points where a scan line gains or loses a crossing.
"""

from __future__ import annotations

import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from .swaths import StripPiece, strip_layout


def _blocks(subs: list[StripPiece]) -> list[list[int]]:
    """Boustrophedon blocks: maximal chains of uniquely linked swaths of consecutive strips."""
    down: dict[int, int] = {}
    for s in subs:
        for b in s.links_up:
            down[b] = down.get(b, 0) + 1
    nxt = {
        a: s.links_up[0]
        for a, s in enumerate(subs)
        if len(s.links_up) == 1 and down.get(s.links_up[0], 0) == 1
    }
    has_prev = set(nxt.values())
    blocks: list[list[int]] = []
    for k in range(len(subs)):
        if k in has_prev:
            continue
        chain = [k]
        while chain[-1] in nxt:
            chain.append(nxt[chain[-1]])
        blocks.append(chain)
    return blocks


def layout(
    parts_rot: list[Polygon],
    w: float,
    with_full: bool,
    holes_rot: BaseGeometry | None = None,
    tol: float = 0.0,
) -> tuple[list[StripPiece], list[list[int]]]:
    subs: list[StripPiece] = []
    if holes_rot is not None and holes_rot.is_empty:
        holes_rot = None
    if holes_rot is not None:
        shapely.prepare(holes_rot)
    for p, q in enumerate(parts_rot):
        part_subs = strip_layout(q, w, p, with_full, holes_rot, tol)
        off = len(subs)
        for s in part_subs:
            s.links_up = [b + off for b in s.links_up]
        subs += part_subs
    return subs, _blocks(subs)
