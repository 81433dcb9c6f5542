"""`fieldrx rx`: field + samples -> prescription file in one go, no database.

plan (geo.coverage) -> grid (geo.grid) -> samples (agronomy.soil) ->
interpolation (agronomy.interpolate) -> rates + meter check (agronomy.rates,
agronomy.prescription) -> export (formats.*). Prints one JSON summary on
stdout; on error prints {"error": ...} (plus per-row errors for samples) and
exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from fieldrx.agronomy.interpolate import DEFAULT_METHOD, METHODS
from fieldrx.agronomy.ratemodels.registry import DEFAULT_MODEL, names, needs_input, rate_model
from fieldrx.geo.planning.kinematics import DEFAULT_HEADLAND_PASSES


class RxError(ValueError):
    """Anything the user can fix; the message says what."""


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the `rx` subcommand to an argparse subparsers object."""
    from fieldrx.formats.export import PACKAGE, PRESCRIPTION, export_formats
    from fieldrx.geo.coverage import CORNERS, HEADINGS

    p = subparsers.add_parser(
        "rx",
        help="field + soil samples -> prescription export (no database)",
        description=__doc__,
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("field", help="field boundary: GeoJSON, KML/KMZ or zipped Shapefile (lon/lat)")
    p.add_argument("--samples", help="soil samples (CSV or GeoJSON); NDVI points for --model ndvi")
    p.add_argument("--samples-epsg", type=int, default=None, help="EPSG of x/y sample columns")
    p.add_argument("--skip-bad-rows", action="store_true", help="import the good sample rows")
    g = p.add_argument_group("plan")
    g.add_argument("--swath-width", type=float, default=2.3, help="implement width, m")
    g.add_argument("--cell-length", type=float, default=5.0, help="cell length, m")
    g.add_argument("--heading", choices=HEADINGS, default="longest_edge")
    g.add_argument("--angle-deg", type=float, default=None, help="with --heading angle")
    g.add_argument("--headland-passes", type=int, default=DEFAULT_HEADLAND_PASSES)
    g.add_argument("--start-corner", choices=CORNERS, default="sw")
    g = p.add_argument_group("rate model")
    g.add_argument("--model", choices=names(), default=DEFAULT_MODEL)
    g.add_argument("--target-yield", type=float, default=2500.0, help="M, kg/ha")
    g.add_argument("--n-fraction", type=float, default=0.25, help="x, N mass fraction of product")
    g.add_argument("--e-kg-per-100kg", type=float, default=5.8, help="e, kg N per 100 kg yield")
    g.add_argument("--k-utilisation", type=float, default=0.342, help="k, fertilizer N use")
    g.add_argument("--uniform-rate", type=float, default=None, help="kg/ha for --model uniform")
    g.add_argument("--ndvi-low", type=float, default=0.24)
    g.add_argument("--rate-at-ndvi-low", type=float, default=375.0)
    g.add_argument("--ndvi-high", type=float, default=0.65)
    g.add_argument("--rate-at-ndvi-high", type=float, default=180.0)
    g.add_argument("--fallback-rate", type=float, default=None, help="kg/ha for no-data cells")
    g = p.add_argument_group("interpolation")
    g.add_argument("--interpolation", choices=METHODS, default=DEFAULT_METHOD)
    g.add_argument("--idw-power", type=float, default=2.0)
    g.add_argument("--idw-radius", type=float, default=None, help="m (default unlimited)")
    g.add_argument(
        "--variogram",
        choices=("linear", "power", "gaussian", "spherical", "exponential", "hole-effect"),
        default="spherical",
    )
    g = p.add_argument_group("machine")
    g.add_argument("--speed-min-kmh", type=float, default=3.0)
    g.add_argument("--speed-max-kmh", type=float, default=9.0)
    g.add_argument(
        "--calibration",
        default=None,
        help="metering calibration JSON (default seed 001: 237.2 r - 404.4 g/min, 30-130 r/min)",
    )
    g.add_argument(
        "--no-meter-check", action="store_true", help="do not flag rates outside the meter range"
    )
    g.add_argument("--lag-s", type=float, default=1.52, help="job package: lag time")
    g.add_argument("--controller", default="ladrc", help="job package: controller name")
    g = p.add_argument_group("output")
    g.add_argument(
        "--format",
        choices=export_formats(PRESCRIPTION) + export_formats(PACKAGE),
        default="geojson",
    )
    g.add_argument("-o", "--out", required=True, help="output file")
    g.add_argument("--product", default="fertilizer")
    g.add_argument("--grid-cell-m", type=float, default=None, help="ISO grid cell size, m")
    p.set_defaults(func=run)
    return p


# the option (argparse dest) that gives each model parameter; a parameter without one
# keeps its model's default (agronomy.ratemodels)
PARAM_OPTIONS = {
    "target_yield_kg_ha": "target_yield",
    "n_fraction": "n_fraction",
    "e_kg_per_100kg": "e_kg_per_100kg",
    "k_utilisation": "k_utilisation",
    "rate_kg_ha": "uniform_rate",
    "ndvi_low": "ndvi_low",
    "rate_at_low_kg_ha": "rate_at_ndvi_low",
    "ndvi_high": "ndvi_high",
    "rate_at_high_kg_ha": "rate_at_ndvi_high",
}


def _model_params(args: argparse.Namespace) -> dict[str, Any]:
    """The chosen model's parameters from their options."""
    model = rate_model(args.model)
    out: dict[str, Any] = {}
    for param in model.params:
        dest = PARAM_OPTIONS.get(param.name)
        if dest is None:
            continue
        value = getattr(args, dest)
        if value is None:
            raise RxError(f"--model {model.name} needs --{dest.replace('_', '-')}")
        out[param.name] = value
    return out


def _interp_params(args: argparse.Namespace) -> dict[str, Any]:
    if args.interpolation == "idw":
        return {"power": args.idw_power, "radius_m": args.idw_radius}
    if args.interpolation == "kriging":
        return {"variogram_model": args.variogram}
    return {}


def build(args: argparse.Namespace) -> tuple[bytes, dict[str, Any]]:
    """Run the whole pipeline; returns (file bytes, summary)."""
    from fieldrx_edge.metering import (
        SEED001_CALIBRATION,
        LinearCalibration,
        TableCalibration,
        calibration_from_dict,
    )

    from fieldrx.agronomy.prescription import RateRules, prescribe
    from fieldrx.agronomy.rates import MeterCheck
    from fieldrx.agronomy.soil import read_soil_samples
    from fieldrx.formats.field_import import read_fields
    from fieldrx.geo.coverage import plan_coverage
    from fieldrx.geo.crs import epsg_for_geometry, lonlat_to_utm_xy, to_utm
    from fieldrx.geo.grid import build_grid

    timings: dict[str, float] = {}
    t = time.perf_counter()
    path = Path(args.field)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RxError(f"cannot read {path}: {exc}") from exc
    fields = read_fields(path.name, data)
    props, field_ll = fields[0]
    field_name = props.get("name") or path.stem
    epsg = epsg_for_geometry(field_ll)
    field_utm = to_utm(field_ll, epsg)
    plan = plan_coverage(
        field_utm,
        swath_width_m=args.swath_width,
        heading=args.heading,
        angle_deg=args.angle_deg,
        headland_passes=args.headland_passes,
        start_corner=args.start_corner,
    )
    cells = build_grid(plan, field_utm, cell_length_m=args.cell_length, epsg=epsg)
    timings["plan_grid_s"] = time.perf_counter() - t

    summary: dict[str, Any] = {
        "field": field_name,
        "n_fields_in_file": len(fields),
        "utm_epsg": epsg,
        "field_area_ha": round(field_utm.area / 1e4, 4),
        "n_swaths": len(plan.swaths),
        "n_cells": len(cells),
    }
    metrics = plan.metrics()
    summary["heading_deg"] = metrics.get("heading_deg")

    t = time.perf_counter()
    xy = vals = None
    if needs_input(args.model):
        if not args.samples:
            raise RxError(f"--model {args.model} needs --samples")
        spath = Path(args.samples)
        try:
            sdata = spath.read_bytes()
        except OSError as exc:
            raise RxError(f"cannot read {spath}: {exc}") from exc
        model_input = rate_model(args.model).input
        assert model_input is not None
        column = model_input.column
        imp = read_soil_samples(
            spath.name, sdata, args.samples_epsg, args.skip_bad_rows, field_ll, column
        )
        summary["samples"] = imp.summary()
        if imp.rejected:
            raise RxError(f"sample import rejected: {len(imp.errors)} error(s)", summary)
        ll = imp.lonlat()
        x, y = lonlat_to_utm_xy(ll[:, 0], ll[:, 1], epsg)
        xy = np.column_stack([x, y])
        vals = imp.values(column)
    timings["samples_s"] = time.perf_counter() - t

    meter = None
    cal: LinearCalibration | TableCalibration = SEED001_CALIBRATION
    if args.calibration:
        try:
            cal = calibration_from_dict(json.loads(args.calibration))
        except (ValueError, KeyError, TypeError) as exc:
            raise RxError(f"bad --calibration: {exc}") from exc
    if not args.no_meter_check:
        meter = MeterCheck.from_kmh(cal, args.swath_width, args.speed_min_kmh, args.speed_max_kmh)

    t = time.perf_counter()
    rx = prescribe(
        cells,
        args.model,
        _model_params(args),
        xy,
        vals,
        interpolation=args.interpolation,
        interpolation_params=_interp_params(args),
        rules=RateRules(meter=meter, fallback_rate_kg_ha=args.fallback_rate),
    )
    cells = cells.with_rates(rx.rate_kg_ha, rx.flags)
    timings["prescription_s"] = time.perf_counter() - t
    s = rx.summary(cells.area_m2, seq=cells.seq)
    s["flagged_seq"] = (s.get("flagged_seq") or [])[:50]
    summary["prescription"] = s

    t = time.perf_counter()
    fmt = args.format
    from fieldrx.formats.export import PACKAGE, ExportOptions, export_formats, export_prescription

    if fmt not in export_formats(PACKAGE):
        opts = ExportOptions(
            field_name=field_name,
            boundary_wgs84=field_ll,
            product_name=args.product,
            grid_cell_m=args.grid_cell_m,
            properties={"field": field_name, "model": args.model},
        )
        out, _media, _name = export_prescription(cells, fmt, opts)
    else:
        from fieldrx.formats.jobpackage import JobPackageSpec, build_job_package, package_size

        pkg = build_job_package(
            cells,
            field_utm,
            JobPackageSpec(
                job_id=0,
                machine_id=0,
                prescription_id=0,
                prescription_version=1,
                field_name=field_name,
                implement_width_m=args.swath_width,
                lag_s=args.lag_s,
                calibration=cal,
                controller={"name": args.controller},
                speed_min_m_s=args.speed_min_kmh / 3.6,
                speed_max_m_s=args.speed_max_kmh / 3.6,
                product=args.product,
            ),
        )
        out = pkg.to_json()
        summary["job_package"] = {**package_size(pkg), "checksum": pkg.checksum}
    timings["export_s"] = time.perf_counter() - t
    summary["format"] = fmt
    summary["out"] = str(args.out)
    summary["bytes"] = len(out)
    summary["timings_s"] = {k: round(v, 4) for k, v in timings.items()}
    return out, summary


def run(args: argparse.Namespace) -> int:
    from fieldrx.agronomy.interpolate import InterpolationError
    from fieldrx.agronomy.prescription import PrescriptionError
    from fieldrx.agronomy.ratemodels.registry import RateModelError
    from fieldrx.agronomy.rates import MeterRangeError
    from fieldrx.agronomy.soil import SoilFormatError
    from fieldrx.formats import FormatError
    from fieldrx.geo import PlanningError

    t0 = time.perf_counter()
    try:
        out, summary = build(args)
        Path(args.out).write_bytes(out)
    except (
        RxError,
        FormatError,
        PlanningError,
        SoilFormatError,
        InterpolationError,
        PrescriptionError,
        RateModelError,
        MeterRangeError,
        OSError,
        shapely.errors.GEOSException,
    ) as exc:
        err: dict[str, Any] = {"error": str(exc.args[0] if exc.args else exc)}
        if isinstance(exc, RxError) and len(exc.args) > 1:
            err.update(exc.args[1])
        print(json.dumps(err))
        print(f"fieldrx rx: error: {err['error']}", file=sys.stderr)
        return 2
    summary["elapsed_s"] = round(time.perf_counter() - t0, 4)
    print(json.dumps(summary))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fieldrx")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    args = parser.parse_args(["rx", *(sys.argv[1:] if argv is None else argv)])
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
