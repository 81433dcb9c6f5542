"""`fieldrx plan`: plan a field's coverage path and grid from a GeoJSON file, no database.

Prints one JSON object: n_swaths, n_turns, heading_deg, working_length_m,
nonworking_length_m, coverage_pct, overlap_pct, outside_pct, route_outside_m,
route_in_holes_m, n_cells, elapsed_s.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import MultiPolygon, Polygon, shape

from fieldrx.geo import PlanningError
from fieldrx.geo.coverage import CORNERS, HEADINGS, plan_coverage
from fieldrx.geo.crs import epsg_for_geometry, to_utm, to_wgs84
from fieldrx.geo.grid import build_grid, check_grid_cost
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES, DEFAULT_TURN_RADIUS_M
from fieldrx.geo.validate import BoundaryError, validate_boundary


def load_field(path: str | Path) -> Polygon | MultiPolygon:
    """Field boundary (lon/lat) from a GeoJSON Feature, FeatureCollection (first) or geometry.

    The boundary goes through the same validation as the API's fields
    (:func:`fieldrx.geo.validate.validate_boundary`): a self-intersecting traced boundary
    is refused with where it crosses itself instead of being planned.
    """
    try:
        doc: Any = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise PlanningError(f"cannot read GeoJSON {path}: {exc}") from exc
    if isinstance(doc, dict) and doc.get("type") == "FeatureCollection":
        feats = doc.get("features") or []
        if not feats:
            raise PlanningError(f"{path}: the FeatureCollection has no features")
        doc = feats[0]
    if isinstance(doc, dict) and doc.get("type") == "Feature":
        doc = doc.get("geometry")
    if not isinstance(doc, dict) or doc.get("type") not in ("Polygon", "MultiPolygon"):
        got = doc.get("type") if isinstance(doc, dict) else type(doc).__name__
        raise PlanningError(f"{path}: expected a Polygon or MultiPolygon, got {got}")
    try:
        geom = shape(doc)
    except (ValueError, TypeError, IndexError, shapely.errors.GEOSException) as exc:
        raise PlanningError(f"{path}: invalid geometry: {exc}") from exc
    x0, y0, x1, y1 = geom.bounds
    if not (-180 <= x0 <= x1 <= 180 and -90 <= y0 <= y1 <= 90):
        raise PlanningError(f"{path}: coordinates are not WGS84 lon/lat (bounds {geom.bounds})")
    try:
        valid = validate_boundary(doc)
    except BoundaryError as exc:
        raise PlanningError(f"{path}: {exc.where}: {exc.message}") from exc
    return valid.geometry


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the `plan` subcommand to an argparse subparsers object."""
    p = subparsers.add_parser(
        "plan",
        help="plan coverage path + grid for a GeoJSON field (no database)",
        description=__doc__,
    )
    p.add_argument("field", help="GeoJSON file (Feature, FeatureCollection or geometry, lon/lat)")
    p.add_argument("--swath-width", type=float, default=2.3, help="implement width w, m")
    p.add_argument("--cell-length", type=float, default=5.0, help="cell length L, m")
    p.add_argument("--heading", choices=HEADINGS, default="optimal")
    p.add_argument(
        "--angle-deg",
        type=float,
        default=None,
        help="swath azimuth, degrees clockwise from north (with --heading angle)",
    )
    p.add_argument("--headland-passes", type=int, default=DEFAULT_HEADLAND_PASSES)
    p.add_argument("--headland-order", choices=("first", "last"), default="first")
    p.add_argument("--start-corner", choices=CORNERS, default="sw")
    p.add_argument("--min-cell-fraction", type=float, default=0.1)
    p.add_argument(
        "--turn-radius",
        type=float,
        default=DEFAULT_TURN_RADIUS_M,
        help="minimum turning radius of the machine, m (turns are drivable paths)",
    )
    p.add_argument(
        "--reverse", action="store_true", help="the machine may reverse (fishtail turns)"
    )
    p.add_argument(
        "--pattern",
        choices=("boustrophedon", "skip", "auto"),
        default="boustrophedon",
        help="swath order in a block: neighbours, skip-row (U-turns only), or the faster",
    )
    p.add_argument("--out", help="write the cells as a GeoJSON FeatureCollection")
    p.add_argument("--route-out", help="write the whole route as a GeoJSON LineString")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    try:
        field_ll = load_field(args.field)
        epsg = epsg_for_geometry(field_ll)
        field_utm = to_utm(field_ll, epsg)
        check_grid_cost(field_utm.area, args.swath_width, args.cell_length)
        plan = plan_coverage(
            field_utm,
            swath_width_m=args.swath_width,
            heading=args.heading,
            angle_deg=args.angle_deg,
            headland_passes=args.headland_passes,
            start_corner=args.start_corner,
            headland_order=args.headland_order,
            turn_radius_m=args.turn_radius,
            reverse=args.reverse,
            pattern=args.pattern,
        )
        grid = build_grid(
            plan,
            field_utm,
            cell_length_m=args.cell_length,
            min_cell_fraction=args.min_cell_fraction,
            epsg=epsg,
        )
    except PlanningError as exc:
        if args.json:
            print(json.dumps({"error": str(exc)}))
        print(f"fieldrx plan: error: {exc}", file=sys.stderr)
        return 2
    out: dict[str, Any] = dict(plan.metrics())
    out["n_cells"] = len(grid)
    out["cells_uncovered_m2"] = round(grid.uncovered_m2, 3)
    out["epsg"] = epsg
    out["elapsed_s"] = round(time.perf_counter() - t0, 4)
    if args.out:
        Path(args.out).write_text(json.dumps(grid.to_geojson()))
    if args.route_out:
        route = to_wgs84(plan.route(), epsg)
        feat = {
            "type": "Feature",
            "geometry": json.loads(shapely.to_geojson(route)),
            "properties": {
                k: out[k]
                for k in ("n_swaths", "n_turns", "heading_deg", "turn_radius_m", "turn_kinds")
            },
        }
        Path(args.route_out).write_text(json.dumps(feat))
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:22s} {v}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fieldrx")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    args = parser.parse_args(["plan", *(sys.argv[1:] if argv is None else argv)])
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
