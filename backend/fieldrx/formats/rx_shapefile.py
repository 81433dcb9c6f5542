"""Prescription Shapefiles from other software in: polygons with a rate column, mapped by the user.

Other FMIS and rate controllers write a zipped Shapefile of polygons (zones or
cells) with a numeric rate column whose name and unit vary ("RATE",
"Tgt_Rate_kg", "N_lbac" ...). The import has a mapping step: the preview
lists the numeric columns (``numeric_columns``) with a suggestion, the user
picks the rate column, its unit and the rate outside the polygons, and
``rx_from_items`` turns the features into the same ``RxIn`` an ISOXML zone
prescription becomes (``services.imports`` stores it).

The Shapefile itself is read by ``field_import.read_shapefile_zip_fields``
(polygons, .prj reprojection to WGS84, feature-indexed errors).
"""

from __future__ import annotations

import math
from typing import Any

import shapely

from fieldrx.formats import FormatError
from fieldrx.formats.isoxml_import import RxIn

# unit -> factor to kg/ha (1 lb/ac = 0.45359237 kg / 0.40468564 ha)
UNITS = {"kg/ha": 1.0, "lb/ac": 0.45359237 / 0.40468564224, "g/m2": 10.0, "t/ha": 1000.0}
# volume rates -> l/ha; times the product's density (kg/l) -> kg/ha
VOLUME_UNITS = {"l/ha": 1.0, "gal/ac": 3.785411784 / 0.40468564224}
SUGGESTED = ("RATE", "RATE_KG_HA", "TGTRATE", "TARGET", "TGT_RATE", "RX_RATE", "PRODUCT", "N")


def _number(v: Any) -> float | None:
    if isinstance(v, bool) or v is None:
        return None
    if isinstance(v, int | float):
        return float(v)
    try:
        return float(str(v).strip())
    except ValueError:
        return None


def numeric_columns(items: list[tuple[dict[str, Any], Any]]) -> dict[str, dict[str, float]]:
    """Columns whose every value is a finite number: count, min, max."""
    out: dict[str, dict[str, float]] = {}
    if not items:
        return out
    for name in items[0][0]:
        vals = [_number(p.get(name)) for p, _ in items]
        if all(v is not None and math.isfinite(v) for v in vals):
            nums = [float(v) for v in vals if v is not None]
            out[name] = {"count": len(nums), "min": min(nums), "max": max(nums)}
    return out


def suggest_rate_column(columns: dict[str, Any]) -> str | None:
    upper = {c.upper(): c for c in columns}
    for s in SUGGESTED:
        if s in upper:
            return upper[s]
    return None


def rx_from_items(
    items: list[tuple[dict[str, Any], Any]],
    rate_column: str,
    unit: str,
    default_rate_kg_ha: float,
    name: str,
    product: str,
    density_kg_l: float | None = None,
) -> RxIn:
    """A zone prescription from the mapped features (first feature wins where they overlap)."""
    if unit in VOLUME_UNITS:
        if density_kg_l is None:
            raise FormatError(f"{unit} is a volume rate: give the product's density (kg/l)")
        factor = VOLUME_UNITS[unit] * density_kg_l
    elif unit in UNITS:
        factor = UNITS[unit]
    else:
        raise FormatError(f"unit {unit!r} is not one of {sorted(UNITS) + sorted(VOLUME_UNITS)}")
    if not (math.isfinite(default_rate_kg_ha) and default_rate_kg_ha >= 0):
        raise FormatError(f"default rate {default_rate_kg_ha} must be a number >= 0")
    if items and rate_column not in items[0][0]:
        raise FormatError(
            f"column {rate_column!r} is not in the file (columns: {sorted(items[0][0])})"
        )
    zones = []
    for i, (props, geom) in enumerate(items):
        v = _number(props.get(rate_column))
        if v is None or not math.isfinite(v) or v < 0:
            raise FormatError(
                f"feature {i}: {rate_column}={props.get(rate_column)!r} is not a rate >= 0"
            )
        zones.append((round(v * factor, 4), shapely.make_valid(geom)))
    return RxIn(
        ref=rate_column,
        name=name,
        field_ref="",
        product=product,
        kind="shapefile zones",
        ddi=0,
        unit="kg/ha",
        default_rate_kg_ha=default_rate_kg_ha,
        zones=zones,
    )
