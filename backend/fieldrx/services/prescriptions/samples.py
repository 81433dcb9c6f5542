"""A model's per-cell input from the field's soil samples: the samples read from
PostGIS, interpolated onto the plan's cells, or classified into zones.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.interpolate import interpolate_to_cells
from fieldrx.agronomy.ratemodels.registry import rate_model, rate_models
from fieldrx.agronomy.zones import zone_cell_values
from fieldrx.db.models import Field, SoilSample
from fieldrx.geo.crs import lonlat_to_utm_xy
from fieldrx.services.prescriptions.params import RxError, canonical_model


def field_samples(
    session: Session, field_id: int, column: str, epsg: int
) -> tuple[np.ndarray, np.ndarray]:
    """UTM xy and values of the field's samples that have ``column``."""
    col = getattr(SoilSample, column)
    stmt = select(func.ST_X(SoilSample.geom), func.ST_Y(SoilSample.geom), col).where(
        SoilSample.field_id == field_id, col.is_not(None)
    )
    if column == "n_mg_kg":  # seed 001 eq. 19-21 read alkali-hydrolysable N only
        stmt = stmt.where(SoilSample.n_form == "alkali_hydrolysable")
    rows = session.execute(stmt.order_by(SoilSample.id)).all()
    if not rows:
        return np.zeros((0, 2)), np.zeros(0)
    a = np.asarray(rows, dtype=float)
    x, y = lonlat_to_utm_xy(a[:, 0], a[:, 1], epsg)
    return np.column_stack([x, y]), a[:, 2]


def interpolate_field_samples(
    session: Session,
    field: Field,
    cells: CellTable,
    model: str,
    interpolation: str,
    interpolation_params: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The field's samples of the model's input column interpolated onto the cells:
    (values, no_data, description). A cell without data is NaN in ``values``."""
    inp = rate_model(model).input
    assert inp is not None
    column = inp.column
    xy, z = field_samples(session, field.id, column, field.utm_epsg)
    if len(z) == 0:
        what = "soil samples with n_mg_kg" if column == "n_mg_kg" else "samples with ndvi"
        other = (
            session.scalars(
                select(SoilSample.n_form)
                .where(SoilSample.field_id == field.id, SoilSample.n_mg_kg.is_not(None))
                .distinct()
            ).all()
            if column == "n_mg_kg"
            else []
        )
        if other:
            raise RxError(
                f"model {model!r} needs alkali-hydrolysable soil N (seed 001 eq. 19-21); "
                f"field {field.id}'s samples hold {' and '.join(sorted(other))} N, which the "
                "model cannot read as such: import alkali-hydrolysable N, or use another model"
            )
        raise RxError(
            f"model {model!r} needs {what} on field {field.id}: import them first "
            f"(POST /api/v1/fields/{field.id}/soil-samples)"
        )
    res = interpolate_to_cells(
        interpolation, cells.polygons_utm, cells.centroids_utm, xy, z, **interpolation_params
    )
    values = np.where(res.no_data, np.nan, np.asarray(res.values, dtype=float))
    info = {"method": res.method, "n_samples": int(len(z)), **res.info}
    return values, np.asarray(res.no_data, dtype=bool) | np.isnan(values), info


def soil_zone_source(
    session: Session,
    field: Field,
    model: str,
    interpolation: str,
    interpolation_params: dict[str, Any],
    k: int,
    min_area_m2: float,
) -> Callable[[CellTable], tuple[np.ndarray, dict[str, Any]]]:
    """``cell_source`` of a zone prescription from soil samples: the model's input property
    (``agronomy.ratemodels``: soil n_mg_kg, sample NDVI) interpolated onto the plan's cells,
    classified into ``k`` zones and smoothed to ``min_area_m2`` (``agronomy.zones``, the
    same zoning as imagery NDVI zones); each zone's cells get the zone's mean, so the model
    gives one rate per zone."""
    canonical, _ = canonical_model(model, {})
    reg = rate_models()
    inp = reg.get(canonical).input if canonical in reg else None
    if inp is None:
        which = ", ".join(f"{m.name}: {m.input.label}" for m in reg if m.input is not None)
        raise RxError(f"zones need a model with a per-cell input ({which}), got {model!r}")
    column = inp.column

    def source(cells: CellTable) -> tuple[np.ndarray, dict[str, Any]]:
        values, _, info = interpolate_field_samples(
            session, field, cells, canonical, interpolation, interpolation_params
        )
        per_cell, zoning = zone_cell_values(
            values,
            k,
            polygons=cells.polygons_utm,
            area_m2=cells.area_m2,
            min_area_m2=min_area_m2,
            value_name=column,
        )
        return per_cell, {**info, **zoning}

    return source
