"""Prescription building, fallback, meter flags, edits, zone painting, summary."""

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.cells import FLAG_BITS, CellTable, flag_names, flag_strings
from fieldrx.agronomy.prescription import (
    PrescriptionError,
    RateRules,
    apply_cell_edits,
    build_prescription,
    paint_zone,
    prescribe,
    summarize,
)
from fieldrx.agronomy.ratemodels.nutrient_balance import nutrient_balance_rate
from fieldrx.agronomy.rates import MeterCheck, MeterRangeError
from fieldrx_edge.metering import LinearCalibration

EPSG = 32649
NB = {"target_yield_kg_ha": 2500, "n_fraction": 0.25}


def _cells():
    return CellTable.rectangle(EPSG, 600000.0, 3556000.0, 3, 4, 2.3, 5.0)


def _meter():
    return MeterCheck.from_kmh(LinearCalibration(), 2.3, 3.0, 9.0)  # 583.6 .. 882.1 kg/ha


def test_build_with_no_data_fallback_and_meter_flags():
    v = np.array([100.0, np.nan, 30.0, 500.0])
    p = build_prescription(
        "nutrient_balance", NB, 4, v, rules=RateRules(meter=_meter()), area_m2=np.ones(4)
    )
    # fallback = model rate at the mean of cells with data = F(210)
    assert p.fallback_rate_kg_ha == pytest.approx(float(nutrient_balance_rate(210.0, 2500, 0.25)))
    lo, hi = p.meter_range_kg_ha
    assert p.rate_kg_ha[0] == pytest.approx(700.367, abs=1e-3)
    # outside the meter range: kept as computed, flagged (never silently rewritten)
    assert p.rate_kg_ha[2] == pytest.approx(906.433, abs=1e-3) and p.rate_kg_ha[2] > hi
    assert p.rate_kg_ha[3] < lo  # ~114 kg/ha < floor 584
    assert [flag_names(f) for f in p.flags] == [
        [],
        ["no_data"] + (["below_meter_range"] if p.fallback_rate_kg_ha < lo else []),
        ["above_meter_range"],
        ["below_meter_range"],
    ]


def test_explicit_fallback_and_errors():
    p = build_prescription(
        "nutrient_balance", NB, 2, np.array([np.nan, np.nan]),
        rules=RateRules(fallback_rate_kg_ha=650),
    )
    np.testing.assert_allclose(p.rate_kg_ha, [650, 650])
    assert (p.flags == FLAG_BITS["no_data"]).all()
    with pytest.raises(PrescriptionError, match="no cell has data"):
        build_prescription("nutrient_balance", NB, 2, np.array([np.nan, np.nan]))
    with pytest.raises(PrescriptionError, match="needs per-cell values"):
        build_prescription("ndvi", {}, 2)


def test_prescribe_from_samples_cell_mean_and_uniform():
    cells = _cells()
    xy = cells.centroids_utm[:3]
    p = prescribe(
        cells,
        "nutrient_balance",
        NB,
        xy,
        np.array([100.0, 100.0, 100.0]),
        interpolation="cell_mean",
    )
    assert p.rate_kg_ha[:3] == pytest.approx([700.367] * 3, abs=1e-3)
    assert (p.flags[3:] == FLAG_BITS["no_data"]).all()
    assert p.info["interpolation"]["method"] == "cell_mean"
    u = prescribe(cells, "uniform", {"rate_kg_ha": 600}, rules=RateRules(meter=_meter()))
    assert (u.rate_kg_ha == 600).all() and (u.flags == 0).all()
    nd = prescribe(cells, "ndvi", {}, xy, np.array([0.24, 0.65, 0.445]), interpolation="idw")
    assert nd.rate_kg_ha[:3] == pytest.approx([375, 180, 277.5])


def test_edits_make_new_arrays_and_flag_manual():
    cells = _cells()
    p = prescribe(cells, "uniform", {"rate_kg_ha": 700})
    old_rates, old_flags = p.rate_kg_ha.copy(), p.flags.copy()
    r2, f2 = apply_cell_edits(cells.seq, p.rate_kg_ha, p.flags, {2: 650.0, 4: 0.0}, _meter())
    np.testing.assert_array_equal(p.rate_kg_ha, old_rates)  # version n unchanged
    np.testing.assert_array_equal(p.flags, old_flags)
    assert r2[2] == 650.0 and flag_names(f2[2]) == ["manual"]
    assert r2[4] == 0.0 and flag_strings(f2)[4] == "manual"  # 0 = meter off, always possible
    # a rate the meter cannot deliver is refused, naming the limit and the speed
    with pytest.raises(MeterRangeError, match=r"cell 4: 2000 kg/ha is above .* 9 km/h: 882\.1"):
        apply_cell_edits(cells.seq, p.rate_kg_ha, p.flags, {4: 2000.0}, _meter())
    with pytest.raises(MeterRangeError, match=r"cell 4: 150 kg/ha is below .* 3 km/h: 583\.6"):
        apply_cell_edits(cells.seq, p.rate_kg_ha, p.flags, {4: 150.0}, _meter())
    with pytest.raises(PrescriptionError, match="cell 999"):
        apply_cell_edits(cells.seq, p.rate_kg_ha, p.flags, {999: 1.0})
    with pytest.raises(PrescriptionError, match="cell 0: rate"):
        apply_cell_edits(cells.seq, p.rate_kg_ha, p.flags, {0: -5.0})


def test_zone_painting_by_polygon():
    cells = _cells()
    rates = np.full(len(cells), 700.0)
    flags = np.zeros(len(cells), dtype=np.uint16)
    # first swath (x 600000..600002.3), southern two cells (y 3556000..3556010)
    zone = shapely.box(599990, 3555990, 600001.5, 3556010.0)
    r2, f2, n = paint_zone(cells.centroids_utm, rates, flags, zone, 600.0)
    assert n == 2
    painted = np.flatnonzero(r2 == 600.0)
    assert sorted(cells.seq[painted].tolist()) == [0, 1]  # swath 0 runs north from y0
    assert (f2[painted] == FLAG_BITS["zone"]).all() and (rates == 700.0).all()
    with pytest.raises(PrescriptionError, match="invalid"):
        bowtie = shapely.Polygon([(0, 0), (1, 1), (1, 0), (0, 1)])
        paint_zone(cells.centroids_utm, rates, flags, bowtie, 600.0)


def test_summary_hand_values():
    r = np.array([100.0, 200.0, 300.0, 0.0])
    a = np.array([10000.0, 5000.0, 5000.0, 2000.0])
    f = np.array([0, FLAG_BITS["no_data"], FLAG_BITS["manual"], 0], dtype=np.uint16)
    s = summarize(r, f, a, bins=3, seq=np.array([1, 2, 3, 4]))
    assert s["area_ha"] == pytest.approx(2.2)
    assert s["product_kg"] == pytest.approx(100 + 100 + 150)
    assert s["rate_mean_kg_ha"] == pytest.approx(350 / 2.2)
    assert (s["rate_min_kg_ha"], s["rate_max_kg_ha"]) == (0.0, 300.0)
    assert s["histogram"]["counts"] == [1, 1, 2]
    assert s["histogram"]["area_m2"] == [2000.0, 10000.0, 10000.0]
    assert s["flagged"]["no_data"] == 1 and s["flagged"]["manual"] == 1
    assert s["n_flagged"] == 2 and s["flagged_seq"] == [2, 3]
