"""Stage: drivable turns between swaths and drivable transfers.

The old route joined the end of one swath to the start of the next by a straight segment
(a 2.3 m sideways jump no tractor can drive). Here every connection is a path whose
curvature never exceeds 1 / r, r the machine's minimum turning radius:

* **Dubins paths** (L. E. Dubins, Am. J. Math. 79 (1957) 497-516; the closed forms of the
  six words LSL, RSR, LSR, RSL, RLR, LRL follow A. Shkel and V. Lumelsky, Robotics and
  Autonomous Systems 34 (2001) 179-202): the shortest forward path between two poses.
  Between neighbouring swaths with gap >= 2r this is the U-turn (arc, straight, arc);
  with gap < 2r it is the bulb (omega) turn, an RLR / LRL word that swings out first.
* **Fishtail (K-turn)** when the machine may reverse and the gap is < 2r: a forward
  quarter circle, a straight reverse of 2r - gap, a forward quarter circle. It is chosen
  when its time (reverse slower, a stop at each cusp; see ``Machine``) beats the bulb.
* **Transfers** (block to block, ring to ring, around holes) follow the router's
  shortest path inside the field: Dubins paths chained through its waypoints, each
  waypoint passed along the bisector of its two legs.

A turn reaches beyond the inner area by about r to 2r; the deepest reach is the headland
width the turns need (``required_headland_m``), and the planner warns when the headland
passes are fewer. A turn that would cross a hole, or a transfer that would leave the
field when the plan has headland passes, is replaced by the routed polyline (not
drivable); those are counted (``undrivable_connections``) and warned about.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from .kinematics import Machine

TWO_PI = 2.0 * math.pi
ARC_STEP_RAD = math.radians(5.0)  # polyline step on arcs: curvature error < 0.04 %


def _mod2pi(a: float) -> float:
    return a % TWO_PI


def _words(alpha: float, beta: float, d: float) -> list[tuple[str, tuple[float, float, float]]]:
    """The six Dubins words in normalised form (unit radius; Shkel & Lumelsky 2001)."""
    sa, sb, ca, cb = math.sin(alpha), math.sin(beta), math.cos(alpha), math.cos(beta)
    cab = math.cos(alpha - beta)
    out: list[tuple[str, tuple[float, float, float]]] = []
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)
    if p2 >= 0:
        th = math.atan2(cb - ca, d + sa - sb)
        out.append(("LSL", (_mod2pi(th - alpha), math.sqrt(p2), _mod2pi(beta - th))))
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)
    if p2 >= 0:
        th = math.atan2(ca - cb, d - sa + sb)
        out.append(("RSR", (_mod2pi(alpha - th), math.sqrt(p2), _mod2pi(th - beta))))
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        th = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append(("LSR", (_mod2pi(th - alpha), p, _mod2pi(th - _mod2pi(beta)))))
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        th = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append(("RSL", (_mod2pi(alpha - th), p, _mod2pi(beta - th))))
    c = (6.0 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8.0
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        th = math.atan2(ca - cb, d - sa + sb)
        t = _mod2pi(alpha - th + p / 2.0)
        out.append(("RLR", (t, p, _mod2pi(alpha - beta - t + p))))
    c = (6.0 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8.0
    if abs(c) <= 1:
        p = _mod2pi(TWO_PI - math.acos(c))
        th = math.atan2(ca - cb, d + sa - sb)
        t = _mod2pi(-alpha - th + p / 2.0)
        out.append(("LRL", (t, p, _mod2pi(_mod2pi(beta) - alpha - t + p))))
    return out


def _segment(
    x: float, y: float, th: float, kind: str, amount: float, r: float
) -> tuple[np.ndarray, float, float, float]:
    """Points after (x, y, th) along one segment (arc angle or straight length / r)."""
    if kind == "S":
        d = amount * r
        end = (x + d * math.cos(th), y + d * math.sin(th))
        return np.array([end]), end[0], end[1], th
    n = max(1, math.ceil(amount / ARC_STEP_RAD))
    s = 1.0 if kind == "L" else -1.0
    a = np.linspace(0.0, amount, n + 1)[1:]
    cx, cy = x - s * r * math.sin(th), y + s * r * math.cos(th)
    ang = th + s * a
    pts = np.stack([cx + s * r * np.sin(ang), cy - s * r * np.cos(ang)], axis=1)
    return pts, float(pts[-1, 0]), float(pts[-1, 1]), th + s * amount


def dubins_words(
    p0: np.ndarray, th0: float, p1: np.ndarray, th1: float, r: float
) -> list[tuple[np.ndarray, str]]:
    """Every Dubins word from pose (p0, th0) to (p1, th1), shortest first, as sampled
    polylines (exact end points); words whose closed form misses the end pose (a wrong
    branch on numerically degenerate input) are left out."""
    dx, dy = float(p1[0] - p0[0]), float(p1[1] - p0[1])
    d = math.hypot(dx, dy) / r
    theta = math.atan2(dy, dx) if d > 1e-12 else 0.0
    alpha, beta = _mod2pi(th0 - theta), _mod2pi(th1 - theta)
    out = []
    for word, params in sorted(_words(alpha, beta, d), key=lambda wp: sum(wp[1])):
        x, y, th = float(p0[0]), float(p0[1]), th0
        pts = [np.array([[x, y]])]
        for kind, amount in zip(word, params, strict=True):
            seg, x, y, th = _segment(x, y, th, kind, amount, r)
            pts.append(seg)
        if math.hypot(x - p1[0], y - p1[1]) > 1e-6 * max(1.0, r):
            continue
        if abs((th - th1 + math.pi) % TWO_PI - math.pi) > 1e-6:
            continue
        coords = np.concatenate(pts)
        coords[-1] = p1
        out.append((coords, word))
    return out


def dubins(
    p0: np.ndarray, th0: float, p1: np.ndarray, th1: float, r: float
) -> tuple[np.ndarray, str] | None:
    """Shortest forward path of curvature <= 1/r from pose (p0, th0) to (p1, th1).

    Returns the sampled polyline (exact end points) and the word, or None when no word
    reaches the end pose (numerically degenerate input).
    """
    words = dubins_words(p0, th0, p1, th1, r)
    return words[0] if words else None


def fishtail(
    p0: np.ndarray, th0: float, p1: np.ndarray, th1: float, r: float
) -> tuple[np.ndarray, float, float] | None:
    """K-turn between antiparallel poses closer than 2r: forward quarter circle, reverse
    straight (2r - gap), forward quarter circle. Returns (polyline, forward m, reverse m),
    None when the poses are not antiparallel or the gap allows a U-turn."""
    if abs(_mod2pi(th1 - th0) - math.pi) > 1e-6:
        return None
    c, s = math.cos(th0), math.sin(th0)
    rel = np.asarray(p1, float) - np.asarray(p0, float)
    bx, by = rel[0] * c + rel[1] * s, -rel[0] * s + rel[1] * c
    gap = abs(by)
    if gap >= 2 * r or gap < 1e-9:
        return None
    sg = 1.0 if by > 0 else -1.0
    xs = max(bx, 0.0)
    q = np.linspace(0.0, math.pi / 2, max(2, math.ceil((math.pi / 2) / ARC_STEP_RAD) + 1))
    arc1 = np.stack([xs + r * np.sin(q), sg * r * (1 - np.cos(q))], axis=1)
    arc2 = np.stack([xs + r * np.cos(q), sg * (gap - r + r * np.sin(q))], axis=1)
    local = np.concatenate([[[0.0, 0.0]], arc1, arc2, [[bx, by]]])
    rot = np.array([[c, s], [-s, c]])
    coords = local @ rot + np.asarray(p0, float)
    coords[0], coords[-1] = p0, p1
    keep = np.r_[True, np.hypot(*np.diff(coords, axis=0).T) > 1e-9]
    forward = abs(bx) + math.pi * r
    return coords[keep], forward, 2 * r - gap


@dataclass
class Connection:
    """One non-working path: its geometry and how it is driven."""

    line: LineString
    kind: str  # "u_turn", "bulb", "fishtail", "transfer", "routed" (not drivable)
    reverse_m: float = 0.0
    cusps: int = 0


@dataclass
class TurnReport:
    """What the turn stage tells the metrics and the user."""

    connections: list[Connection] = field(default_factory=list)
    required_headland_m: float = 0.0
    undrivable: int = 0
    kinds: dict[str, int] = field(default_factory=dict)


def _end_heading(line: LineString, at_end: bool) -> float:
    c = np.asarray(line.coords)
    seg = c[-1] - c[-2] if at_end else c[1] - c[0]
    if at_end:
        k = len(c) - 1
        while k > 0 and np.hypot(*(c[k] - c[k - 1])) < 1e-9:
            k -= 1
        seg = c[k] - c[k - 1] if k > 0 else seg
    else:
        k = 1
        while k < len(c) - 1 and np.hypot(*(c[k] - c[k - 1])) < 1e-9:
            k += 1
        seg = c[k] - c[k - 1]
    return math.atan2(seg[1], seg[0])


def _reach(coords: np.ndarray, p0: np.ndarray, th0: float, p1: np.ndarray) -> float:
    """How far a turn runs beyond the further of its two swath ends (along th0)."""
    u = np.array([math.cos(th0), math.sin(th0)])
    return float(((coords - p0) @ u).max() - max(0.0, float((p1 - p0) @ u)))


TurnKey = tuple[float, float, float, float, bool, float]


def turn_between(
    p0: np.ndarray,
    th0: float,
    p1: np.ndarray,
    th1: float,
    m: Machine,
    room: float,
    cache: dict[TurnKey, Connection] | None = None,
) -> Connection:
    """:func:`_turn_local` in the frame of the first swath's end, memoised: the turns of
    a block repeat (same gap, same stagger), so a 1,000 ha field computes a few."""
    c, s = math.cos(th0), math.sin(th0)
    d = np.asarray(p1, float) - np.asarray(p0, float)
    bx, by = d[0] * c + d[1] * s, -d[0] * s + d[1] * c
    dth = _mod2pi(th1 - th0)
    key = (round(bx, 6), round(by, 6), round(dth, 9), m.turn_radius_m, m.reverse, room)
    hit = cache.get(key) if cache is not None else None
    if hit is None:
        hit = _turn_local(np.zeros(2), 0.0, np.array([bx, by]), dth, m, room)
        if cache is not None:
            cache[key] = hit
    rot = np.array([[c, s], [-s, c]])
    coords = np.asarray(hit.line.coords) @ rot + p0
    coords[0], coords[-1] = p0, p1
    return Connection(LineString(coords), hit.kind, hit.reverse_m, hit.cusps)


def _turn_local(
    p0: np.ndarray, th0: float, p1: np.ndarray, th1: float, m: Machine, room: float
) -> Connection:
    """A drivable turn between two swath ends: Dubins (U or bulb), or with reverse the
    fishtail when the bulb does not fit the ``room`` the headland leaves and the
    fishtail reaches less far, or when both fit and the fishtail is faster."""
    r = m.turn_radius_m
    best = dubins(p0, th0, p1, th1, r)
    if best is None:
        return Connection(LineString([p0, p1]), "routed")
    coords, _word = best
    line = LineString(coords)
    c, s = math.cos(th0), math.sin(th0)
    gap = abs(-(p1[0] - p0[0]) * s + (p1[1] - p0[1]) * c)
    kind = "u_turn" if gap >= 2 * r - 1e-9 else "bulb"
    if m.reverse:
        ft = fishtail(p0, th0, p1, th1, r)
        if ft is not None:
            bulb_reach, ft_reach = _reach(coords, p0, th0, p1), _reach(ft[0], p0, th0, p1)
            if bulb_reach > room + 1e-9:
                better = ft_reach < bulb_reach
            else:
                better = ft_reach <= room + 1e-9 and m.time_s(ft[1], ft[2], 2) < m.time_s(
                    line.length
                )
            if better:
                return Connection(LineString(ft[0]), "fishtail", ft[2], 2)
    return Connection(line, kind)


def _transfer(waypoints: np.ndarray, th0: float, th1: float, r: float) -> LineString | None:
    """Dubins paths chained through the router's waypoints (bisector headings)."""
    n = len(waypoints)
    heads = [th0]
    for i in range(1, n - 1):
        a = waypoints[i] - waypoints[i - 1]
        b = waypoints[i + 1] - waypoints[i]
        ua, ub = a / max(np.hypot(*a), 1e-12), b / max(np.hypot(*b), 1e-12)
        bis = ua + ub
        heads.append(math.atan2(bis[1], bis[0]) if np.hypot(*bis) > 1e-9 else math.atan2(*ub[::-1]))
    heads.append(th1)
    parts: list[np.ndarray] = []
    for i in range(n - 1):
        res = dubins(waypoints[i], heads[i], waypoints[i + 1], heads[i + 1], r)
        if res is None:
            return None
        parts.append(res[0] if not parts else res[0][1:])
    return LineString(np.concatenate(parts))


@dataclass
class _Env:
    """Where connections must stay: holes to avoid, the field when there is a headland."""

    holes_core: BaseGeometry | None
    field_ok: BaseGeometry | None
    holes_full: BaseGeometry | None = None


def _acceptable(lines: list[LineString], env: _Env, in_field: np.ndarray | bool) -> np.ndarray:
    """Connections that avoid holes and (where ``in_field``) stay inside the field."""
    arr = np.array(lines, dtype=object)
    ok = np.ones(len(arr), bool)
    if env.holes_core is not None and len(arr):
        ok &= ~shapely.intersects(arr, env.holes_core)
    check = np.broadcast_to(np.asarray(in_field, bool), ok.shape)
    if env.field_ok is not None and check.any():
        idx = np.flatnonzero(check)
        ok[idx] &= shapely.covers(env.field_ok, arr[idx])
    return ok


def connect(
    swaths: list[Any],
    route: Callable[[np.ndarray, np.ndarray], LineString],
    machine: Machine,
    fld: BaseGeometry,
    region: BaseGeometry,
    headland_m: float,
    w: float,
) -> TurnReport:
    """Drivable connections between consecutive swaths (see module docstring).

    ``swaths`` have ``line`` (driving direction) and ``kind`` ("inner" / "headland");
    ``route(a, b)`` is the shortest path inside the field; ``headland_m`` the width
    of the headland passes (0: none).
    """
    holes = [Polygon(ri) for p in shapely.get_parts(fld) for ri in getattr(p, "interiors", [])]
    core = shapely.union_all([h.buffer(-(w / 2 + 1e-6)) for h in holes]) if holes else None
    full = shapely.union_all([h.buffer(-1e-6) for h in holes]) if holes else None
    env = _Env(
        None if core is None or core.is_empty else core,
        fld.buffer(1e-6) if headland_m > 0 else None,
        None if full is None or full.is_empty else full,
    )
    room = headland_m
    for g in (env.holes_core, env.holes_full):
        if g is not None:
            shapely.prepare(g)
    if env.field_ok is not None:
        shapely.prepare(env.field_ok)
    cons: list[Connection] = []
    cache: dict[TurnKey, Connection] = {}
    is_turn = np.zeros(max(0, len(swaths) - 1), bool)
    for k, (a, b) in enumerate(zip(swaths[:-1], swaths[1:], strict=True)):
        p0, p1 = np.asarray(a.line.coords[-1]), np.asarray(b.line.coords[0])
        th0, th1 = _end_heading(a.line, True), _end_heading(b.line, False)
        if a.kind == "inner" and b.kind == "inner" and a.block == b.block:
            is_turn[k] = True
            cons.append(turn_between(p0, th0, p1, th1, machine, room, cache))
        else:
            cons.append(Connection(LineString([p0, p1]), "routed"))  # set below
    rep = TurnReport(cons)
    rep.required_headland_m = _turn_depth(
        [c for c, t in zip(cons, is_turn, strict=True) if t], region
    )
    # a headland too narrow for the turns lets transfers reach outside like the turns
    outside_ok = headland_m + 1e-6 < rep.required_headland_m
    for k in np.flatnonzero(~is_turn).tolist():
        a, b = swaths[k], swaths[k + 1]
        p0, p1 = np.asarray(a.line.coords[-1]), np.asarray(b.line.coords[0])
        th0, th1 = _end_heading(a.line, True), _end_heading(b.line, False)
        cons[k] = _transfer_between(p0, th0, p1, th1, route, machine, env, outside_ok)
    # a turn's driving line never enters a hole (its implement may overhang the edge),
    # and with a headland wide enough for the turns it stays in the field: a turn
    # between staggered swath ends can cut across a notch of the boundary however
    # close to the region it stays, and is then driven as a transfer
    strict = _Env(env.holes_full, None if outside_ok else env.field_ok)
    ok = _acceptable([c.line for c in cons], strict, is_turn)
    for k in np.flatnonzero(~ok & is_turn).tolist():
        a, b = swaths[k], swaths[k + 1]
        p0, p1 = np.asarray(a.line.coords[-1]), np.asarray(b.line.coords[0])
        th0, th1 = _end_heading(a.line, True), _end_heading(b.line, False)
        cons[k] = _transfer_between(p0, th0, p1, th1, route, machine, env, outside_ok)
    for c in cons:
        rep.kinds[c.kind] = rep.kinds.get(c.kind, 0) + 1
    rep.undrivable = rep.kinds.get("routed", 0)
    return rep


def _transfer_between(
    p0: np.ndarray,
    th0: float,
    p1: np.ndarray,
    th1: float,
    route: Callable[[np.ndarray, np.ndarray], LineString],
    machine: Machine,
    env: _Env,
    outside_ok: bool = False,
) -> Connection:
    """A drivable transfer (block to block, ring to ring, into and out of the rings).

    Options, in order: Dubins paths chained through the router's waypoints (follows
    the headland around corners and holes), then every direct Dubins word, shortest
    first. The first that avoids the holes and (with a headland) stays in the field is
    taken; then the old rule (the chain inside the field, clear of the holes' cores w/2
    in from their edges); without a headland, or with one too narrow for the turns
    (``outside_ok``), the first that avoids the holes (its reach
    beyond the field counted in ``route_outside_m`` like the turns). Otherwise the
    routed polyline (``routed``: not drivable, warned about).
    """
    path = route(p0, p1)
    r = machine.turn_radius_m
    opts = [_transfer(np.asarray(path.coords), th0, th1, r)]
    opts += [LineString(c) for c, _ in dubins_words(p0, th0, p1, th1, r)]
    lines = [o for o in opts if o is not None]
    if not lines:
        return Connection(path, "routed")
    strict = _Env(env.holes_full, env.field_ok)
    inside = _acceptable(lines, strict, True)
    clear = _acceptable(lines, strict, False)
    # with a headland the route must stay in the field: a sharp routed polyline inside
    # (counted, warned) beats a drivable one outside; without one, outside is allowed
    checks = (inside, _acceptable(lines[:1], env, True))
    for good in checks if env.field_ok is not None and not outside_ok else (*checks, clear):
        if good.any():
            return Connection(lines[int(np.argmax(good))], "transfer")
    return Connection(path, "routed")


def _turn_depth(turns: list[Connection], region: BaseGeometry) -> float:
    """How far turns between inner swaths reach beyond the inner area (the headland they
    need: with that much headland, a turn's centre line stays inside the field)."""
    if region.is_empty:
        return 0.0
    pts = [np.asarray(c.line.coords) for c in turns if c.kind != "routed"]
    if not pts:
        return 0.0
    xy = np.concatenate(pts)
    shapely.prepare(region)
    out = ~shapely.contains_xy(region, xy[:, 0], xy[:, 1])
    if not out.any():
        return 0.0
    return float(shapely.distance(region, shapely.points(xy[out])).max())
