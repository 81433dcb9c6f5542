"""Stage: the order in which swaths are driven, behind one interface.

Blocks (boustrophedon cells) are driven back and forth; a ``BlockOrder`` chooses the
sequence of blocks and the configuration of each (bottom-up or top-down, first pass +x
or -x). ``ExactOrder`` solves it exactly (Held-Karp DP over routed distances) for the
few blocks real fields decompose into; ``GreedyOrder`` takes the nearest block entry
next. Headland rings are driven nearest-first, each re-started two turning radii ahead
of the machine so it can swing over with an S-curve.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from shapely.geometry import LineString, Point
from shapely.geometry.base import BaseGeometry

from .frame import Frame
from .headland import rotate_ring
from .kinematics import Machine
from .model import StripGeometry, Swath
from .swaths import StripPiece
from .turns import TurnKey, turn_between

ROUTED_ORDER_MAX_BLOCKS = 40
EXACT_ORDER_MAX_BLOCKS = 8
Dist = Callable[[np.ndarray, np.ndarray], float]
Step = tuple[int, list[int], int]  # block, swath order, first direction
PATTERNS = ("boustrophedon", "skip", "auto")


def block_configs(subs: list[StripPiece], block: list[int]) -> list[tuple[list[int], int]]:
    """The 4 ways to drive a block: bottom-up or top-down, first pass +x or -x."""
    return [(order, d) for order in (block, block[::-1]) for d in (1, -1)]


def endpoints(
    subs: list[StripPiece], order: list[int], first_dir: int
) -> tuple[tuple[float, float], tuple[float, float]]:
    s0, s1 = subs[order[0]], subs[order[-1]]
    last_dir = first_dir if len(order) % 2 == 1 else -first_dir
    start = (s0.x0 if first_dir > 0 else s0.x1, s0.y)
    end = (s1.x1 if last_dir > 0 else s1.x0, s1.y)
    return start, end


def _turns_length(subs: list[StripPiece], order: list[int], first_dir: int) -> float:
    """Straight-line length of the turns inside a block driven in this configuration."""
    total = 0.0
    d = first_dir
    for a, b in zip(order[:-1], order[1:], strict=True):
        sa, sb = subs[a], subs[b]
        xa = sa.x1 if d > 0 else sa.x0
        xb = sb.x1 if d > 0 else sb.x0  # the next swath starts where this one ended
        total += math.hypot(xa - xb, sb.y - sa.y)
        d = -d
    return total


def order_blocks_exact(
    subs: list[StripPiece],
    blocks: list[list[int]],
    frame: Frame,
    pos: np.ndarray,
    from_corner: bool,
    dist: Callable[[np.ndarray, np.ndarray], float],
) -> list[tuple[int, list[int], int]]:
    """Block order and configuration with the least non-working travel (Held-Karp DP).

    Cost = routed hops between blocks (shortest paths inside the field) + turns inside
    the blocks; the first hop is from the start corner (straight) or from the end of the
    headland (routed). Exact for the few blocks real fields decompose into.
    """
    nb = len(blocks)
    cfgs = [block_configs(subs, b) for b in blocks]
    starts, ends, inner = [], [], []
    for b in range(nb):
        for order, d in cfgs[b]:
            st, en = endpoints(subs, order, d)
            starts.append(frame.inv(np.asarray(st)))
            ends.append(frame.inv(np.asarray(en)))
            inner.append(_turns_length(subs, order, d))
    nn = 4 * nb
    first = np.array(
        [
            float(math.dist(pos, starts[i])) if from_corner else dist(pos, starts[i])
            for i in range(nn)
        ]
    ) + np.array(inner)
    hop = np.full((nn, nn), np.inf)
    for i in range(nn):
        for j in range(nn):
            if i // 4 != j // 4:
                hop[i, j] = dist(ends[i], starts[j]) + inner[j]
    full = (1 << nb) - 1
    cost = np.full((1 << nb, nn), np.inf)
    back = np.full((1 << nb, nn), -1, dtype=np.int64)
    for i in range(nn):
        cost[1 << (i // 4), i] = first[i]
    for mask in range(1, full + 1):
        row = cost[mask]
        live = np.flatnonzero(np.isfinite(row))
        if not len(live):
            continue
        for j in range(nn):
            bit = 1 << (j // 4)
            if mask & bit:
                continue
            cand = row[live] + hop[live, j]
            k = int(np.argmin(cand))
            nm = mask | bit
            if cand[k] < cost[nm, j]:
                cost[nm, j] = cand[k]
                back[nm, j] = live[k]
    j = int(np.argmin(cost[full]))
    mask = full
    chain = []
    while j >= 0:
        chain.append(j)
        pj = int(back[mask, j])
        mask ^= 1 << (j // 4)
        j = pj
    chain.reverse()
    return [(i // 4, *cfgs[i // 4][i % 4]) for i in chain]


class BlockOrder(Protocol):
    """Chooses the block sequence and each block's configuration from position pos."""

    def __call__(
        self,
        subs: list[StripPiece],
        blocks: list[list[int]],
        frame: Frame,
        pos: np.ndarray,
        from_corner: bool,
    ) -> list[Step]: ...


@dataclass
class ExactOrder:
    """Held-Karp over blocks x configurations with routed hops (see order_blocks_exact)."""

    dist: Dist

    def __call__(
        self,
        subs: list[StripPiece],
        blocks: list[list[int]],
        frame: Frame,
        pos: np.ndarray,
        from_corner: bool,
    ) -> list[Step]:
        return order_blocks_exact(subs, blocks, frame, pos, from_corner, self.dist)


@dataclass
class GreedyOrder:
    """Nearest block entry next (routed distance; straight from the start corner)."""

    dist: Dist

    def __call__(
        self,
        subs: list[StripPiece],
        blocks: list[list[int]],
        frame: Frame,
        pos: np.ndarray,
        from_corner: bool,
    ) -> list[Step]:
        left = list(range(len(blocks)))
        first = from_corner
        out: list[Step] = []
        while left:
            b, order, d = self._next(subs, blocks, frame, pos, left, first)
            left.remove(b)
            first = False
            out.append((b, order, d))
            _, end = endpoints(subs, order, d)
            pos = frame.inv(np.asarray(end))
        return out

    def _next(
        self,
        subs: list[StripPiece],
        blocks: list[list[int]],
        frame: Frame,
        pos: np.ndarray,
        left: list[int],
        first: bool,
    ) -> Step:
        # candidates by straight-line distance; the routed distance is never shorter,
        # so stop once the straight distance exceeds the best routed one
        cands = []
        for b in left:
            for order, d in block_configs(subs, blocks[b]):
                start, _ = endpoints(subs, order, d)
                s_utm = frame.inv(np.asarray(start))
                cands.append((float(math.dist(pos, s_utm)), b, order, d, s_utm))
        cands.sort(key=lambda c: c[0])
        best = None
        for eu, b, order, d, s_utm in cands:
            if best is not None and eu >= best[0] - 1e-9:
                break
            cost = eu if first else self.dist(pos, s_utm)
            if best is None or cost < best[0] - 1e-9:
                best = (cost, b, order, d)
        assert best is not None
        return best[1], best[2], best[3]


def choose_order(n_blocks: int, routed: Dist) -> BlockOrder:
    """Exact for 2..8 blocks; greedy (routed up to 40 blocks, straight beyond) otherwise."""
    if 2 <= n_blocks <= EXACT_ORDER_MAX_BLOCKS:
        return ExactOrder(routed)
    if n_blocks <= ROUTED_ORDER_MAX_BLOCKS:
        return GreedyOrder(routed)
    return GreedyOrder(lambda a, b: float(math.dist(a, b)))


def block_swaths(
    subs: list[StripPiece], steps: list[Step], frame: Frame, first_index: int
) -> list[Swath]:
    """Inner swaths of the chosen steps, alternating direction within each block."""
    out: list[Swath] = []
    for b, order, d in steps:
        for j, k in enumerate(order):
            s = subs[k]
            dj = d if j % 2 == 0 else -d
            xa, xb = (s.x0, s.x1) if dj > 0 else (s.x1, s.x0)
            line = LineString(frame.inv(np.array([[xa, s.y], [xb, s.y]])))
            strip = StripGeometry(y=s.y, x0=s.x0, x1=s.x1, clip=s.comp, full=s.full)
            out.append(Swath(first_index + len(out), line, "inner", b, dj, strip))
    return out


def ring_swaths(
    rings: list[tuple[int, LineString, BaseGeometry]],
    pos: np.ndarray,
    first_index: int,
    lead_m: float,
) -> list[Swath]:
    """Headland rings nearest-first from pos, each started ``lead_m`` ahead."""
    out: list[Swath] = []
    left = list(range(len(rings)))
    while left:
        pt = Point(pos)
        k = min(left, key=lambda k: (rings[k][1].distance(pt), rings[k][0]))
        left.remove(k)
        k_pass, ring, band = rings[k]
        ring = rotate_ring(ring, pos, lead_m)
        strip = StripGeometry(band=band, ring_pass=k_pass)
        out.append(Swath(first_index + len(out), ring, "headland", -1 - k, 1, strip))
        pos = np.asarray(ring.coords[-1])
    return out


def order_swaths(
    subs: list[StripPiece],
    blocks: list[list[int]],
    rings: list[tuple[int, LineString, BaseGeometry]],
    frame: Frame,
    start: np.ndarray,
    routed: Dist,
    headland_first: bool,
    lead_m: float,
) -> list[Swath]:
    """All swaths in driving order: rings then blocks, or blocks then rings."""
    swaths: list[Swath] = []
    pos = start

    def rings_part() -> None:
        nonlocal pos
        swaths.extend(ring_swaths(rings, pos, len(swaths), lead_m))
        if swaths:
            pos = np.asarray(swaths[-1].line.coords[-1])

    def blocks_part() -> None:
        nonlocal pos
        steps = choose_order(len(blocks), routed)(subs, blocks, frame, pos, not swaths)
        swaths.extend(block_swaths(subs, steps, frame, len(swaths)))
        if swaths:
            pos = np.asarray(swaths[-1].line.coords[-1])

    for part in (rings_part, blocks_part) if headland_first else (blocks_part, rings_part):
        part()
    return swaths


def skip_sequence(m: int, s: int) -> list[int]:
    """Visiting order of m neighbouring swaths in which consecutive swaths are s or s+1
    apart (skip-row / set pattern): groups of 2s swaths driven s-1, 2s-1, s-2, 2s-2, ...,
    0, s, the next group entered 2s-1 swaths further on; a remainder shorter than a
    group is driven back and forth. With s w >= 2r every turn is a U-turn."""
    out: list[int] = []
    g = 0
    while g + 2 * s <= m:
        for i in range(s - 1, -1, -1):
            out += [g + i, g + s + i]
        g += 2 * s
    return out + list(range(g, m))


def _sequence_time(
    subs: list[StripPiece],
    seq: list[int],
    m: Machine,
    room: float,
    cache: dict[TurnKey, object],
) -> float:
    """Turn time of driving ``seq`` back and forth (in the frame: headings 0 / pi)."""
    total, d = 0.0, 1
    for a, b in zip(seq[:-1], seq[1:], strict=True):
        sa, sb = subs[a], subs[b]
        p0 = np.array([sa.x1 if d > 0 else sa.x0, sa.y])
        p1 = np.array([sb.x1 if d > 0 else sb.x0, sb.y])
        th0 = 0.0 if d > 0 else math.pi
        c = turn_between(p0, th0, p1, th0 + math.pi, m, room, cache)  # type: ignore[arg-type]
        total += m.time_s(c.line.length - c.reverse_m, c.reverse_m, c.cusps)
        d = -d
    return total


def block_sequences(
    subs: list[StripPiece],
    blocks: list[list[int]],
    w: float,
    m: Machine,
    room: float,
    pattern: str,
) -> list[list[int]]:
    """Each block's swath sequence: boustrophedon, skip-row, or (``auto``) the one whose
    turns take less time with this machine (the objective picks the pattern)."""
    if pattern == "boustrophedon":
        return blocks
    s = max(2, math.ceil(2.0 * m.turn_radius_m / w - 1e-9))
    cache: dict[TurnKey, object] = {}
    out = []
    for blk in blocks:
        if len(blk) < 2 * s:
            out.append(blk)
            continue
        skip = [blk[i] for i in skip_sequence(len(blk), s)]
        if pattern == "skip" or _sequence_time(subs, skip, m, room, cache) < _sequence_time(
            subs, blk, m, room, cache
        ):
            out.append(skip)
        else:
            out.append(blk)
    return out
