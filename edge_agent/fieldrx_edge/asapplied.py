"""The as-applied kernel (seed 001 eq. 16-18), pure numpy: shared by the simulator and the server.

One definition of every as-applied figure, so the edge simulator, the server's
report and the job map's tiles cannot drift apart:

* time: a telemetry record describes one GNSS fix; its time ``t`` is the fix
  time and its ``fix_period_s`` the receiver's fix interval
  (``protocol.TelemetryRecord``); ``fix_periods`` is how long each record's
  metering state lasted. Integrating over the gap to the next record's time
  instead makes the mass depend on how the records were stamped;
* metered mass: flow from the shaft speed through the machine's calibration
  (``metering.flow_g_min_many``), trapezoid between a record and the next one
  (``metered_mass_g``): M = q t (seed 001 eq. 17);
* landing (seed 001 eq. 16 / sec. 2.3): what is metered during [t, t + dt]
  leaves the outlet T_lag later, so it lands along the track between the
  positions at t + T_lag and t + dt + T_lag, each moved ``forward_m`` along the
  heading (antenna to outlet); ``landing_segments``;
* which cell: the landing segment is split among the cells' polygons (their
  4-corner rectangles, or their real shapes where the job package / plan
  carries one) in proportion of its length in each; where cells overlap the
  record's own cell (the one the agent metered for) wins, else the lowest path
  index; mass in no cell is "outside" (``landed_mass``);
* driven length (eq. 17's v t): the cell's driving line (the centre lines, rear
  to front cut-edge midpoints, of the cell and its same-swath neighbours, 5 m
  straight on at a swath's ends) inside the cell's polygon; one definition for
  rectangles and real shapes (``driven_length``; a whole rectangle gives its
  length);
* M1 = M v t l / 36 g with v t the driven length (docs/science.md erratum: grams),
  i.e. rate * width * length / 10 (``m1_g``); theta = (1 - |M1 - M2| / M1) *
  100 % (eq. 18, ``theta_pct``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from fieldrx_edge.metering import Calibration, flow_g_min_many
from fieldrx_edge.planar import GridHash, Polygons, Region, split_segments

MISSED_FIX = 1.5  # a gap beyond this many fix periods means fixes were missed


def fix_periods(
    t: np.ndarray, period: np.ndarray | None = None, max_gap_s: float = 2.0
) -> np.ndarray:
    """Duration (s) each record's metering state lasted, records sorted by time.

    Records without a fix period (format 1) last until the next record's time,
    0 across a gap longer than ``max_gap_s`` (an outage: nothing is known about
    it); the last record lasts the median gap. A record that carries its fix
    period (finite, > 0) lasts that period, whatever the spacing of the time
    stamps (jitter, or stamps squeezed together), except where the next record
    comes clearly later (more than ``MISSED_FIX`` periods, up to ``max_gap_s``):
    fixes were missed there (the agent holds the last rate through a short loss
    of fix) and the gap is the duration, as for records without a period.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    if n == 0:
        return np.zeros(0)
    gaps = np.diff(t)
    typical = float(np.median(gaps)) if len(gaps) else 0.0
    dts = np.append(gaps, typical)
    dts = np.where(dts > max_gap_s, 0.0, np.maximum(dts, 0.0))
    if period is not None:
        p = np.asarray(period, dtype=float)
        known = np.isfinite(p) & (p > 0)
        missed = known & (dts > MISSED_FIX * np.where(known, p, 0.0))
        dts = np.where(known & ~missed, p, dts)
    return dts


def metered_mass_g(flow_g_s: np.ndarray, dts: np.ndarray) -> np.ndarray:
    """Grams metered in each record's period: trapezoid between this record's flow and the
    next one's (the shaft speed moves between fixes), the last record at its own flow."""
    flow = np.asarray(flow_g_s, dtype=float)
    nxt = np.append(flow[1:], flow[-1:]) if len(flow) else flow
    return np.asarray(0.5 * (flow + nxt) * np.asarray(dts, dtype=float))


EDGE_RUN_M = 5.0  # the driving line runs on this far past a swath's first and last cell


def flow_g_s(cal: Calibration | None, rpm: np.ndarray, fallback_g_s: np.ndarray) -> np.ndarray:
    """Metered flow (g/s) from the shaft speed; ``fallback_g_s`` where no speed is known
    (no calibration, or a record without a shaft speed)."""
    rpm = np.asarray(rpm, dtype=float)
    if cal is None:
        return np.asarray(fallback_g_s, dtype=float)
    ok = np.isfinite(rpm)
    return np.where(ok, flow_g_min_many(cal, np.where(ok, rpm, 0.0)) / 60.0, fallback_g_s)


@dataclass
class Cells:
    """The cells of a job in path order: rectangles (n, 8) UTM, swath, optional real shapes,
    and the field (its rings, UTM): nothing counts outside it (the agent never applies there,
    and a plan's edge cells may keep a rectangle reaching past it)."""

    corners: np.ndarray
    swath: np.ndarray
    polygons: Polygons
    index: GridHash
    field: Region | None = None

    @classmethod
    def build(
        cls,
        corners: Any,
        swath: Any,
        shapes: dict[int, list[list[float]]] | None = None,
        field_rings: list[Any] | None = None,
    ) -> Cells:
        c = np.asarray(corners, dtype=float).reshape(-1, 8)
        polys = Polygons.from_cells(c, shapes)
        fld = Region(field_rings) if field_rings else None
        return cls(c, np.asarray(swath, dtype=np.int64), polys, GridHash(polys.bbox), fld)

    def pieces(
        self, cell: np.ndarray, p0: np.ndarray, p1: np.ndarray, seg_of: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cut segments p0-p1 at the edges of the paired cells (pair i: segment seg_of[i],
        cell cell[i]) and of the field: (segment, t0, t1) of every piece inside the field."""
        n_seg = len(p0)
        if seg_of is None:
            seg_of = np.arange(len(cell))
        pair, t = self.polygons.segment_crossings(cell, p0[seg_of], p1[seg_of])
        seg, cut = seg_of[pair], t
        if self.field is not None:
            fs, ft = self.field.segment_crossings(p0, p1)
            seg, cut = np.concatenate([seg, fs]), np.concatenate([cut, ft])
        ps, t0, t1 = split_segments(n_seg, seg, cut)
        if self.field is not None:
            tm = 0.5 * (t0 + t1)
            d = p1[ps] - p0[ps]
            ok = self.field.contains(p0[ps, 0] + tm * d[:, 0], p0[ps, 1] + tm * d[:, 1])
            ps, t0, t1 = ps[ok], t0[ok], t1[ok]
        return ps, t0, t1

    @property
    def n(self) -> int:
        return len(self.corners)

    @property
    def area_m2(self) -> np.ndarray:
        """Shoelace area of the rectangles."""
        c = self.corners.reshape(-1, 4, 2)
        x, y = c[..., 0], c[..., 1]
        cross = x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y
        return np.asarray(0.5 * np.abs(np.sum(cross, axis=1)))


def driving_lines(cells: Cells) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cell, p0, p1) segments of every cell's driving line (see the module doc).

    Corners are rear-right, front-right, front-left, rear-left: the centre line
    runs from the rear cut edge's midpoint to the front one's.
    """
    c = cells.corners.reshape(-1, 4, 2)
    n = len(c)
    if n == 0:
        z = np.zeros((0, 2))
        return np.zeros(0, dtype=np.int64), z, z
    rear = (c[:, 3] + c[:, 0]) / 2
    front = (c[:, 1] + c[:, 2]) / 2
    sw = cells.swath
    prev_same = np.zeros(n, dtype=bool)
    prev_same[1:] = sw[1:] == sw[:-1]
    next_same = np.zeros(n, dtype=bool)
    next_same[:-1] = sw[:-1] == sw[1:]
    idx = np.arange(n)
    im, ip = np.maximum(idx - 1, 0), np.minimum(idx + 1, n - 1)
    # a grid whose corners do not follow the travel direction: orient each centre line
    # along the path (from the previous same-swath cell's centre to the next one's)
    cent = c.mean(axis=1)
    along = np.where(next_same[:, None], cent[ip], cent) - np.where(
        prev_same[:, None], cent[im], cent
    )
    back = np.einsum("ij,ij->i", front - rear, along) < 0
    rear, front = np.where(back[:, None], front, rear), np.where(back[:, None], rear, front)
    d = front - rear
    u = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    # polyline: [rear[i-1]] front[i-1] | rear[i] front[i] | rear[i+1] [front[i+1]]
    a0 = np.where(prev_same[:, None], rear[im], rear - EDGE_RUN_M * u)
    a1 = np.where(prev_same[:, None], front[im], rear - EDGE_RUN_M * u)
    b0 = np.where(next_same[:, None], rear[ip], front + EDGE_RUN_M * u)
    b1 = np.where(next_same[:, None], front[ip], front + EDGE_RUN_M * u)
    pts = np.stack([a0, a1, rear, front, b0, b1], axis=1)  # (n, 6, 2)
    p0 = pts[:, :-1].reshape(-1, 2)
    p1 = pts[:, 1:].reshape(-1, 2)
    cell = np.repeat(idx, 5)
    return cell, p0, p1


def driven_length(cells: Cells) -> np.ndarray:
    """Length (m) of each cell's driving line inside the cell's polygon and the field
    (eq. 17's v t)."""
    cell, p0, p1 = driving_lines(cells)
    ps, t0, t1 = cells.pieces(cell, p0, p1)
    tm = 0.5 * (t0 + t1)
    d = p1[ps] - p0[ps]
    inside = cells.polygons.contains(cell[ps], p0[ps, 0] + tm * d[:, 0], p0[ps, 1] + tm * d[:, 1])
    seg_len = np.hypot(d[:, 0], d[:, 1])
    w = ((t1 - t0) * seg_len)[inside]
    return np.bincount(cell[ps][inside], weights=w, minlength=cells.n)


def landing_segments(
    t0: np.ndarray,
    dts: np.ndarray,
    track_t: np.ndarray,
    track_x: np.ndarray,
    track_y: np.ndarray,
    track_heading_deg: np.ndarray,
    lag_s: float,
    forward_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the mass metered over [t0, t0 + dts] lands (eq. 16): (p0, p1, known).

    The track (times sorted) is interpolated linearly at t0 + lag and t0 + dts +
    lag; both points move ``forward_m`` along the interpolated heading. Mass
    whose landing time lies before the track or more than 1 s after it lands
    somewhere unknown (``known`` False).
    """
    t0 = np.asarray(t0, dtype=float)
    ta = t0 + lag_s
    tb = ta + np.asarray(dts, dtype=float)
    if len(track_t) < 2:
        z = np.full((len(t0), 2), np.nan)
        return z, z, np.zeros(len(t0), dtype=bool)
    hd = np.unwrap(np.radians(track_heading_deg), period=2 * np.pi)

    def at(tt: np.ndarray) -> np.ndarray:
        h = np.interp(tt, track_t, hd)
        x = np.interp(tt, track_t, track_x) + forward_m * np.sin(h)
        y = np.interp(tt, track_t, track_y) + forward_m * np.cos(h)
        return np.column_stack([x, y])

    tm = 0.5 * (ta + tb)
    known = (tm >= track_t[0]) & (tm <= track_t[-1] + 1.0)
    return at(ta), at(tb), known


def landed_mass(
    cells: Cells,
    mass_g: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    own: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Per-cell landed mass M2 (g) and the mass landing in no cell (see the module doc).

    ``own`` is each segment's own cell index (-1: none), preferred where cells overlap.
    """
    n = cells.n
    mass_g = np.asarray(mass_g, dtype=float)
    sel = np.flatnonzero(mass_g > 0)
    total = float(mass_g[sel].sum())
    if n == 0 or len(sel) == 0:
        return np.zeros(n), total
    a, b = p0[sel], p1[sel]
    m = mass_g[sel]
    o = np.full(len(sel), -1, dtype=np.int64) if own is None else np.asarray(own)[sel]
    boxes = np.column_stack(
        [np.minimum(a[:, 0], b[:, 0]), np.minimum(a[:, 1], b[:, 1]),
         np.maximum(a[:, 0], b[:, 0]), np.maximum(a[:, 1], b[:, 1])]
    )  # fmt: skip
    q, c = cells.index.pairs(boxes, cells.polygons.bbox)
    if len(q) == 0:
        return np.zeros(n), total
    # cut each segment at every edge of every candidate cell (and of the field), then
    # place each piece
    ps, t0, t1 = cells.pieces(c, a, b, q)
    # candidate cells of each piece's segment (pairs are sorted by segment)
    first = np.searchsorted(q, ps, side="left")
    cnt = np.searchsorted(q, ps, side="right") - first
    piece = np.repeat(np.arange(len(ps)), cnt)
    k = np.repeat(first, cnt) + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    cell = c[k]
    seg = ps[piece]
    tm = 0.5 * (t0 + t1)[piece]
    d = b[seg] - a[seg]
    inside = cells.polygons.contains(cell, a[seg, 0] + tm * d[:, 0], a[seg, 1] + tm * d[:, 1])
    piece, cell, seg = piece[inside], cell[inside], seg[inside]
    # one cell per piece: the segment's own cell, else the lowest index
    rank = np.where(cell == o[seg], -1, cell)
    order = np.lexsort((rank, piece))
    piece, cell = piece[order], cell[order]
    keep = np.ones(len(piece), dtype=bool)
    keep[1:] = piece[1:] != piece[:-1]
    piece, cell = piece[keep], cell[keep]
    w = (t1 - t0)[piece] * m[ps[piece]]
    m2 = np.bincount(cell, weights=w, minlength=n)
    return m2, total - float(m2.sum())


def m1_g(rate_kg_ha: np.ndarray, width_m: float, drive_len_m: np.ndarray) -> np.ndarray:
    """Seed 001 eq. 17: M1 = M v t l / 36 g (v km/h, t s) = rate * width * length / 10."""
    return np.asarray(
        np.asarray(rate_kg_ha, dtype=float) * width_m * np.asarray(drive_len_m) / 10.0
    )


def theta_pct(m1: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Seed 001 eq. 18: theta = (1 - |M1 - M2| / M1) * 100 %; NaN where M1 = 0."""
    m1 = np.asarray(m1, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(m1 > 0, (1.0 - np.abs(m1 - m2) / m1) * 100.0, np.nan)


@dataclass
class RecordsApplied:
    """What the kernel makes of a job's records (arrays in record order)."""

    dts: np.ndarray  # fix period of each record (s)
    mass_g: np.ndarray  # metered in it (g)
    m2_g: np.ndarray  # per cell
    outside_g: float  # landed in no cell, or somewhere unknown


@dataclass(frozen=True)
class RecordColumns:
    """A job's telemetry records as columns, sorted by time (the agent's log).

    ``own`` is each record's cell (index in path order, -1 none); ``fallback_g_s`` the
    flow to use where there is no calibration (the applied rate over the strip).
    ``count`` (bool per record, default all): only these records' mass is placed."""

    t: np.ndarray
    fix_period_s: np.ndarray | None
    x: np.ndarray
    y: np.ndarray
    heading_deg: np.ndarray
    rpm: np.ndarray
    own: np.ndarray
    fallback_g_s: np.ndarray
    count: np.ndarray | None = None


def records_applied(
    cells: Cells,
    rec: RecordColumns,
    cal: Calibration | None,
    lag_s: float,
    forward_m: float,
    max_gap_s: float = 2.0,
) -> RecordsApplied:
    """Seed 001 eq. 16-17 over telemetry records sorted by time (the agent's log).

    ``rec.own`` is each record's cell: preferred where cells overlap, and where the
    record has no position its mass goes there.

    ``rec.count`` (bool per record, default all): only these records' mass is placed
    (``m2_g``, ``outside_g``); the others are context. The thin uplink
    (``fieldrx_edge.uplink.thin``) runs the kernel over a window of the log this
    way: a record's figures depend only on itself, the next record and the
    track up to its landing time, so a window holding those gives the counted
    records exactly what the whole log gives them.
    """
    own, count = rec.own, rec.count
    t = np.asarray(rec.t, dtype=float)
    dts = fix_periods(t, rec.fix_period_s, max_gap_s)
    mass = metered_mass_g(flow_g_s(cal, rec.rpm, rec.fallback_g_s), dts)
    x = np.asarray(rec.x, dtype=float)
    y = np.asarray(rec.y, dtype=float)
    have = np.isfinite(x) & np.isfinite(y)
    hd = np.nan_to_num(np.asarray(rec.heading_deg, dtype=float))
    p0, p1, known = landing_segments(t, dts, t[have], x[have], y[have], hd[have], lag_s, forward_m)
    counted = mass if count is None else np.where(count, mass, 0.0)
    m2, _ = landed_mass(cells, np.where(known & have, counted, 0.0), p0, p1, own)
    nopos = ~have & (own >= 0) & (own < cells.n)
    if count is not None:
        nopos &= count
    if nopos.any():
        m2 += np.bincount(own[nopos], weights=mass[nopos], minlength=cells.n)
    return RecordsApplied(dts, mass, m2, float(counted.sum() - m2.sum()))
