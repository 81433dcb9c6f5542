"""Stage: headland passes (rings around the boundary and the holes) and the inner region.

Pass ``k`` runs on the offset ``(k + 1/2) w`` inside the boundary (and outside every
hole); its band is what its cells are clipped to. The inner region the swaths cover is
the field shrunk by ``h w`` (mitre joins; a subset of the exact erosion, so anything
within ``h w`` of the region stays inside the field).

With a turning radius r the rings are made drivable (:func:`drivable_centre`): the
mitred offset has sharp corners no machine with radius r can follow. Convex corners are
rounded inwards by a morphological opening with r (the union of the r-discs inside the
ring's polygon, J. Serra, *Image Analysis and Mathematical Morphology*, 1982, ch. 2);
a reflex corner (an L's inner corner, the ring around a pond's corner) cannot be
rounded on the boundary side without leaving the field or entering the pond, so the
ring swings inwards around it: an r-disc through the corner is taken out of the
polygon before the opening. Both only remove area, so the rounded ring stays inside
the mitred one: inside the field and clear of every hole. What the rounded corners
leave unworked is reported (``corner_loss``), not hidden in the band the cells use.

Several passes are concentric: pass k is pass 0's ring polygon offset k w inwards, so
pass 0 rounds its convex corners to r + (h - 1) w and every pass turns no tighter than
r, and consecutive passes share their band edges (no gaps between them; what the
rounding leaves unworked lies at the boundary's corners). Where pass 0 is too narrow
for that radius, each pass is rounded on its own.

One owner per square metre: each pass's band is what its rings sweep and no earlier
pass swept, and the inner region gives up what any ring sweeps (:func:`carve`), so the
rings' cells and the inner swaths' cells are two tilings that never overlap (the last
pass's rounded corners sweep into the mitred inner region, and a ring swinging inwards
around a reflex corner dents it).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LinearRing, LineString, MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient
from shapely.ops import substring

from .. import PlanningError
from .boundary import max_extent, min_width, parts

ARC_QUAD_SEGS = 90  # 1 degree steps in the morphology (chord sag 4e-5 r)
BITE_SCALE = 1.02  # reflex bites: radius 1.02 r (curvature 1 / 1.02 r < 1 / r)
RING_SLACK = 1.05  # rings are rounded to 1.05 r: room for the resampling's 3 % error
RING_STEP = 0.1  # the rounded ring is resampled every 0.1 r (about 6 degree steps)
KINK_ROUNDS = 3  # bite-and-open rounds for kinks the closing cannot fill
BAND_TOLERANCE_M = 0.01  # concentric passes' bands follow their rings to within 1 cm


def _vertex_turns(c: np.ndarray) -> tuple[np.ndarray, ...]:
    """At each vertex of a closed ring (coords without the repeated first point): the
    incoming and outgoing edge lengths and unit vectors, the cross product of those (< 0:
    a right turn), the turning angle and whether both edges have a length."""
    e1 = c - np.roll(c, 1, axis=0)
    e2 = np.roll(c, -1, axis=0) - c
    l1, l2 = np.hypot(*e1.T), np.hypot(*e2.T)
    ok = (l1 > 1e-9) & (l2 > 1e-9)
    u1 = e1 / np.where(ok, l1, 1.0)[:, None]
    u2 = e2 / np.where(ok, l2, 1.0)[:, None]
    cross = u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]
    theta = np.arctan2(np.abs(cross), (u1 * u2).sum(1))
    return l1, l2, u1, u2, cross, theta, ok


def _kinks(geom: BaseGeometry, r: float) -> tuple[list[Point], list[Polygon]]:
    """Reflex vertices of geom's rings, resampled as the rings are (:func:`_resampled`),
    whose triple is tighter than 0.99 r -- where two of an opening's r-discs cross --
    and a bite (:func:`_bites`) at each."""
    points: list[Point] = []
    discs: list[Polygon] = []
    for p in parts(geom):
        p = orient(p, 1.0)
        for ring in [p.exterior, *p.interiors]:
            c = np.asarray(_resampled(ring, r).coords)[:-1]
            if len(c) < 3:
                continue
            _, _, u1, u2, cross, theta, ok = _vertex_turns(c)
            chord = np.hypot(*(np.roll(c, -1, axis=0) - np.roll(c, 1, axis=0)).T)
            radius = chord / np.maximum(2.0 * np.sin(theta), 1e-12)
            idx = np.flatnonzero(ok & (cross < 0) & (radius < 0.99 * r))
            points += [Point(q) for q in c[idx]]
            discs += _bites(c, u1, u2, idx, r)
    return points, discs


def _reflex_bites(poly: Polygon, r: float) -> list[Polygon]:
    """r-discs through each reflex vertex of poly that turns tighter than r.

    A vertex turning by theta between edges a and b can be followed with radius r on a
    fillet that uses at most half of each edge when min(a, b) / 2 / tan(theta / 2) >= r
    (a sampled arc of radius >= r passes), but at a reflex vertex that fillet bulges
    outwards, towards the boundary or into a hole; so a reflex vertex that turns tighter
    than r or more than a 5 degree arc step gets a disc of radius
    1.02 r centred r beyond the vertex on the outside bisector, so the boundary of
    ``poly - disc`` passes 0.02 r inside the vertex on a concave arc of radius 1.02 r.
    """
    out = []
    for ring in [poly.exterior, *poly.interiors]:
        c = np.asarray(ring.coords)[:-1]
        if len(c) < 3:
            continue
        l1, l2, u1, u2, cross, theta, ok = _vertex_turns(c)
        fit = 0.5 * np.minimum(l1, l2) / np.maximum(np.tan(0.5 * theta), 1e-12)
        # oriented polygon (exterior CCW, holes CW): its inside is on the left, so a
        # right turn (cross < 0) is a reflex vertex
        # a fillet of a reflex vertex would bulge outwards by r (sec(theta / 2) - 1):
        # more than 0.001 r (a 5 degree arc step's own sag) needs the bite as well
        bulge = r * (1.0 / np.cos(0.5 * theta) - 1.0)
        tight = ok & (cross < -1e-12) & ((fit < r * (1.0 - 1e-9)) | (bulge > 1e-3 * r))
        out += _bites(c, u1, u2, np.flatnonzero(tight), r)
    return out


def _bites(
    c: np.ndarray, u1: np.ndarray, u2: np.ndarray, idx: np.ndarray, r: float
) -> list[Any]:
    """A disc of radius 1.02 r centred r beyond each vertex c[idx] on the outside
    bisector of its edges (unit vectors u1 in, u2 out): the sampled disc (chords sag
    0.001 r) covers the vertex, and the opening's erosion by r leaves a smooth 0.02 r
    arc (not a sliver) that its dilation turns back into the bite's arc."""
    if len(idx) == 0:
        return []
    # the outside bisector of each vertex's edges, as a unit vector; one vectorised
    # buffer call: a sampled arc of many reflex vertices has thousands of bites
    b = np.stack([u1[idx, 1] + u2[idx, 1], -(u1[idx, 0] + u2[idx, 0])], axis=1)
    b /= np.maximum(np.hypot(b[:, 0], b[:, 1]), 1e-12)[:, None]
    centres = shapely.points(c[idx] + r * b)
    return list(shapely.buffer(centres, BITE_SCALE * r, quad_segs=ARC_QUAD_SEGS))


def drivable_centre(poly: Polygon, r: float, convex_r: float | None = None) -> BaseGeometry:
    """The part of a ring's polygon whose boundary has no curvature tighter than 1 / r
    (see module docstring): reflex bites taken out, the opening with r, then the
    closing with r. A subset of ``poly``; empty where the polygon is narrower than 2 r
    (no loop fits).

    The opening alone only bounds the convex curvature: it is the union of the r-discs
    inside the polygon, and where the polygon has a neck narrower than 2 r (the ring
    between a pond and the field edge) the erosion's two tips on either side of the
    neck are less than 2 r apart, so their discs overlap and the two circles cross at a
    sharp reflex corner (a 142 degree kink, circumradius 0.15 m, in
    tests/geo/ring_kink_field.wkt). The closing rolls an r-disc into that wedge and
    replaces the corner with a concave arc of radius r, tangent to both circles, and
    leaves the bites' arcs (radius 1.02 r) and every other r-smooth stretch alone. Only
    the fills at such a corner that lie inside the polygon are kept (a fill may reach
    into a bite: the bite only keeps the ring from bulging at a reflex vertex, and the
    fill is smooth): across an inlet narrower than 2 r the closing would also bridge
    the inlet, outside the field. A kink the closing cannot fill inside the polygon is
    bitten like a reflex vertex and the result opened again (at most ``KINK_ROUNDS``
    times): the ring swings inwards there.

    ``convex_r`` (>= r, default r) rounds the convex corners wider than the reflex ones:
    the outer ring of several concentric passes, whose inward offsets by w, 2 w, ... must
    still turn no tighter than r (:func:`headland_rings`).
    """
    poly = orient(poly, 1.0)
    rc = r if convex_r is None else max(float(convex_r), r)
    bites = _reflex_bites(poly, r)
    cut = poly.difference(shapely.union_all(bites)) if bites else poly
    opened = cut
    for _ in range(KINK_ROUNDS):
        opened = cut.buffer(-rc, quad_segs=ARC_QUAD_SEGS).buffer(rc, quad_segs=ARC_QUAD_SEGS)
        if opened.is_empty:
            return opened
        corners, _ = _kinks(opened, r)
        if not corners:
            return opened
        opened = _filled(opened, poly, corners, r)
        corners, discs = _kinks(opened, r)
        if not corners:
            return opened
        cut = opened.difference(shapely.union_all(discs))
    return opened


def _filled(opened: BaseGeometry, poly: Polygon, corners: list[Point], r: float) -> BaseGeometry:
    """The opening with the closing's fills at its kinks that lie inside ``poly``."""
    closed = opened.buffer(r, quad_segs=ARC_QUAD_SEGS).buffer(-r, quad_segs=ARC_QUAD_SEGS)
    at = shapely.union_all(corners)
    fills = [
        p for p in parts(closed.difference(opened)) if p.distance(at) < 0.2 * r and _inside(p, poly)
    ]
    return shapely.union_all([opened, *fills]).intersection(poly) if fills else opened


def _inside(piece: Polygon, region: BaseGeometry) -> bool:
    """Whether piece lies in region up to GEOS rounding (1e-6 of its area)."""
    return bool(piece.difference(region).area <= 1e-6 * piece.area + 1e-9)


def _pass_centre(field_geom: BaseGeometry, w: float, k: int) -> list[Polygon]:
    """The mitred polygons (interior on the left) whose rings pass k drives."""
    centre = field_geom.buffer(-(k + 0.5) * w, join_style="mitre", mitre_limit=5.0)
    return [orient(p, 1.0) for p in parts(centre)]


def _pass_bands(field_geom: BaseGeometry, w: float, k: int) -> tuple[BaseGeometry, BaseGeometry]:
    centre = field_geom.buffer(-(k + 0.5) * w, join_style="mitre", mitre_limit=5.0)
    outer = field_geom.buffer(-k * w, join_style="mitre", mitre_limit=5.0) if k else field_geom
    inner = field_geom.buffer(-(k + 1) * w, join_style="mitre", mitre_limit=5.0)
    return centre, outer.difference(inner)


def headland_rings(
    field_geom: Polygon | MultiPolygon,
    w: float,
    h: int,
    turn_radius_m: float = 0.0,
    warnings: list[str] | None = None,
) -> list[tuple[int, LineString, BaseGeometry]]:
    """Rings (pass k, centre line, band) of the h headland passes around boundary and holes.

    With ``turn_radius_m`` > 0 the rings are the drivable ones and each pass's band is
    cut to what its rings sweep, so the grid's headland cells never claim a rounded-off
    corner. The passes are concentric (:func:`_concentric_centres`): pass k is the
    outer ring offset k w inwards, so the passes' bands tile the headland without gaps
    between them and what the rounding leaves unworked lies at the boundary's corners.
    Where that does not fit (a ring polygon narrower than twice the outer radius), each
    pass is rounded on its own (:func:`_own_centres`); a ring polygon narrower than 2 r
    keeps its sharp ring, with a warning.
    """
    if h <= 0:
        return []
    if turn_radius_m <= 0:
        out = []
        for k in range(h):
            centre, band = _pass_bands(field_geom, w, k)
            out += [
                (k, LineString(ri.coords), band)
                for p in (orient(q, 1.0) for q in parts(centre))
                for ri in [p.exterior, *p.interiors]
                if ri.length > w
            ]
        return out
    r = RING_SLACK * turn_radius_m
    smooth = _concentric_centres(field_geom, w, h, r)
    concentric = smooth is not None
    if smooth is None:
        smooth = _own_centres(field_geom, w, h, r)
    out = []
    # each pass's band is what its rings sweep in the field and no earlier pass swept:
    # the last pass's rounded corners sweep into the mitred inner region (which
    # :func:`carve` then gives up). Concentric passes share their edges exactly: band k
    # runs from pass k - 1's inner edge to its own (no slivers between the bands).
    taken: BaseGeometry = Polygon()
    edge = field_geom
    for k, polys in enumerate(smooth):
        rings = _pass_rings(k, polys, w, turn_radius_m, warnings)
        if not rings:
            continue
        swept = shapely.union_all([_footprint(ri, w) for ri in rings])
        if concentric:
            # the morphology's 1 degree arcs are far finer than a cell needs: bands (and
            # the carved region) follow them to within BAND_TOLERANCE_M, with a few
            # hundred vertices instead of tens of thousands on a 40-vertex field; where
            # a kink's fix moved a ring off the concentric offset, what it does not
            # sweep is left out (reported with the corners)
            ring_poly = shapely.union_all([p for p, _ in polys]).simplify(BAND_TOLERANCE_M)
            if k == 0:
                edge = field_geom.intersection(ring_poly.buffer(0.5 * w))
            inner = ring_poly.buffer(-0.5 * w)
            band = edge.difference(inner).intersection(swept.buffer(2 * BAND_TOLERANCE_M))
            edge = inner
        else:
            band = field_geom.intersection(swept).difference(taken)
            taken = taken.union(swept)
        out += [(k, ri, band) for ri in rings]
    return out


def _pass_rings(
    k: int,
    polys: list[tuple[Polygon, bool]],
    w: float,
    turn_radius_m: float,
    warnings: list[str] | None,
) -> list[LineString]:
    """The rings of pass k (every ring of its polygons longer than w); a polygon kept
    sharp is said in ``warnings``."""
    rings: list[LineString] = []
    for p, is_smooth in polys:
        for ri in [p.exterior, *p.interiors]:
            rings.append(_resampled(ri, turn_radius_m) if is_smooth else LineString(ri.coords))
        if not is_smooth and warnings is not None:
            warnings.append(
                f"headland pass {k + 1} has a ring narrower than two turning radii "
                f"({2 * turn_radius_m:g} m): it keeps its sharp corners (not drivable)"
            )
    return [ri for ri in rings if ri.length > w]


def _concentric_centres(
    field_geom: BaseGeometry, w: float, h: int, r: float
) -> list[list[tuple[Polygon, bool]]] | None:
    """Per pass, its ring polygons (all smooth), pass k being pass 0's offset k w inwards.

    An inward offset by d turns a convex arc of radius R into one of R - d and a reflex
    arc of radius R into one of R + d, so pass 0 rounds its convex corners to
    r + (h - 1) w and its reflex ones to r, and every pass then turns no tighter than r.
    Where an offset's two sides meet (a neck) it makes a sharp reflex corner; each
    offset is therefore passed through :func:`drivable_centre` with r, which leaves the
    r-smooth stretches alone and fills or bites only such kinks. None when a pass-0
    polygon is too narrow for the outer radius, or a later pass loses a ring polygon
    the mitred pass keeps (the caller then rounds each pass on its own).
    """
    outer = r + (h - 1) * w
    base = []
    for p in _pass_centre(field_geom, w, 0):
        d = parts(drivable_centre(p, r, convex_r=outer))
        if not d:
            return None
        base += d
    out: list[list[tuple[Polygon, bool]]] = []
    for k in range(h):
        polys: list[tuple[Polygon, bool]] = []
        for d in base:
            shrunk = d.buffer(-k * w, quad_segs=ARC_QUAD_SEGS) if k else d
            for q in parts(shrunk):
                polys += [(orient(x, 1.0), True) for x in parts(drivable_centre(q, r))]
        if len(polys) < len(_pass_centre(field_geom, w, k)):
            return None
        out.append(polys)
    return out


def _own_centres(
    field_geom: BaseGeometry, w: float, h: int, r: float
) -> list[list[tuple[Polygon, bool]]]:
    """Per pass, its mitred ring polygons each rounded with r on its own (smooth), or
    kept sharp where a polygon is narrower than 2 r (not smooth)."""
    out = []
    for k in range(h):
        polys: list[tuple[Polygon, bool]] = []
        for poly in _pass_centre(field_geom, w, k):
            smooth = [orient(p, 1.0) for p in parts(drivable_centre(poly, r))]
            polys += [(p, True) for p in smooth] if smooth else [(poly, False)]
        out.append(polys)
    return out


def carve(
    region: BaseGeometry, rings: list[tuple[int, LineString, BaseGeometry]], w: float
) -> tuple[BaseGeometry, BaseGeometry]:
    """The inner region without what the (rounded) rings sweep, and the pieces it drops.

    A ring rounded to the turning radius cuts its convex corners inwards, so its
    implement sweeps a little of the mitred inner region there (and, swinging around a
    pond's corner, along the pond). Two tilings must not claim the same ground: the
    ring's cells keep it (they are driven there), the inner swaths stop short of it.
    What is left of the region beyond a ring's sweep (a sharp corner of the mitred
    region outside the rounded ring) is a piece smaller than w x w that no swath can
    reach without crossing the ring: it is dropped, and counted with the corners the
    rings leave unworked.
    """
    if region.is_empty or not rings:
        return region, Polygon()
    swept = shapely.union_all([band for _, _, band in rings])
    rest = parts(region.difference(swept))
    keep = [p for p in rest if p.area >= w * w]
    dropped = shapely.union_all([p for p in rest if p.area < w * w])
    return (shapely.union_all(keep) if keep else Polygon()), dropped


def _resampled(ring: BaseGeometry, r: float) -> LineString:
    """The rounded ring as a polyline a curvature check can trust: points every 0.1 r
    along the (1 degree) morphology result, then collinear runs merged (Douglas-Peucker
    at 1e-4 r, far below the 1.2e-3 r sag of a 0.1 r chord on an arc of radius r). The
    points lie on the curve, so every triple's circumradius is the curve's radius up to
    the morphology's chord sag -- the junctions of its polygonised arcs (kinks and steps
    of a few millimetres) no longer make tight triples."""
    c = np.asarray(ring.coords)
    cum = np.r_[0.0, np.cumsum(np.hypot(*np.diff(c, axis=0).T))]
    n = max(8, math.ceil(cum[-1] / (RING_STEP * r)))
    d = np.linspace(0.0, cum[-1], n + 1)
    k = np.clip(np.searchsorted(cum, d, side="right") - 1, 0, len(c) - 2)
    t = (d - cum[k]) / np.maximum(cum[k + 1] - cum[k], 1e-300)
    pts = c[k] + np.clip(t, 0.0, 1.0)[:, None] * (c[k + 1] - c[k])
    pts[-1] = pts[0]
    return LineString(pts).simplify(1e-4 * r, preserve_topology=False)


def _footprint(ring: LineString, w: float) -> BaseGeometry:
    """What a closed ring's implement sweeps (a LinearRing: no cap gap at its start)."""
    return LinearRing(ring.coords).buffer(0.5 * w, join_style="mitre", mitre_limit=5.0)


def corner_gaps(
    field_geom: Polygon | MultiPolygon,
    w: float,
    h: int,
    rings: list[tuple[int, LineString, BaseGeometry]],
) -> BaseGeometry:
    """The parts of the mitred headland bands that the (rounded) rings' bands -- what
    their cells hold -- leave out."""
    if not h:
        return Polygon()
    bands = shapely.union_all([_pass_bands(field_geom, w, k)[1] for k in range(h)])
    swept = shapely.union_all([band for _, _, band in rings]) if rings else Polygon()
    return bands.difference(swept)


def corner_loss(
    field_geom: Polygon | MultiPolygon,
    w: float,
    h: int,
    rings: list[tuple[int, LineString, BaseGeometry]],
) -> float:
    """Area (m²) of :func:`corner_gaps`."""
    return float(corner_gaps(field_geom, w, h, rings).area)


def rotate_ring(ring: LineString, pt: np.ndarray, lead: float = 0.0) -> LineString:
    """Closed ring re-started ``lead`` metres after the ring point nearest to pt.

    The lead (2 turning radii) gives the machine room to swing over from the previous
    ring with an S-curve instead of a loop.
    """
    d = (ring.project(Point(pt)) + lead) % ring.length if lead < ring.length else 0.0
    if lead > 0:
        d = _snapped_split(ring, d, lead)
    if d <= 1e-9 or d >= ring.length - 1e-9:
        return ring
    a = substring(ring, d, ring.length)
    b = substring(ring, 0.0, d)
    return LineString(np.concatenate([np.asarray(a.coords), np.asarray(b.coords)[1:]]))


def _snapped_split(ring: LineString, d: float, lead: float) -> float:
    """Where to re-start a ring near ``d``: at a vertex when one is within lead / 8, or
    when d falls on a short edge (a rounded corner's 0.1 r chords). A new vertex a few
    centimetres from a vertex that turns makes a triple tighter than the arc itself."""
    c = np.asarray(ring.coords)
    cum = np.r_[0.0, np.cumsum(np.hypot(*np.diff(c, axis=0).T))]
    k = int(np.clip(np.searchsorted(cum, d, side="right") - 1, 0, len(c) - 2))
    a, b = cum[k], cum[k + 1]
    if min(d - a, b - d) <= lead / 8.0 or b - a <= lead / 4.0:
        return float(a if d - a <= b - d else b)
    return d


def inner_region(
    fld: Polygon | MultiPolygon, w: float, h: int, warnings: list[str]
) -> tuple[BaseGeometry, int]:
    """The area left for inner swaths inside ``h`` headland passes, and the passes used.

    Narrow fields get a plan instead of an error: a field narrower than the
    implement is covered by one pass; passes that leave no inner area give a
    headland-only plan; a field too narrow for even one headland ring gets one pass.
    Each adjustment is a warning in the plan.
    """
    extent = max_extent(fld)
    if w > extent:
        raise PlanningError(
            f"swath width {w} m is wider than the field in every direction "
            f"(longest extent {extent:.2f} m): nothing to plan"
        )
    narrow = min_width(fld)
    if narrow < w:
        warnings.append(
            f"the field is narrower than the implement ({narrow:.2f} m < {w} m): one pass"
        )
    if not h:
        return fld, 0
    region = fld.buffer(-h * w, join_style="mitre", mitre_limit=5.0)
    if not region.is_empty and region.area >= 1e-6:
        return shapely.union_all(parts(region)), h
    if headland_rings(fld, w, h):
        warnings.append(
            f"{h} headland passes of {w} m leave no inner area in this field: headland-only plan"
        )
        return Polygon(), h
    warnings.append(
        f"the field is too narrow for a headland pass of {w} m: planned without headland"
    )
    return fld, 0
