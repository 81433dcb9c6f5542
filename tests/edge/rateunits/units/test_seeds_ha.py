"""seeds/ha: the seed lot's conversion to kg/ha and the Task Controller's raw values for a
count-per-area seeder (DDI 11) and for a mass-rate implement (DDI 6)."""

from __future__ import annotations

import pytest
from fieldrx_edge.isobus.tc_mapping import RateUnits, from_raw, to_raw
from fieldrx_edge.rateunits.registry import RateUnitError, unit_of

MAIZE = {"tkw_g": 320.0, "germination_pct": 95.0}


def test_the_worked_example() -> None:
    """80 000 seeds/ha x 320 g / 1e6 / 0.95 = 26.95 kg/ha (the module's docstring)."""
    seeds = unit_of("seeds/ha")
    assert seeds.to_kg_ha(80_000, MAIZE) == pytest.approx(26.947, abs=1e-3)
    assert seeds.from_kg_ha(26.947368, MAIZE) == pytest.approx(80_000, rel=1e-6)


def test_a_lot_without_germination_or_with_an_impossible_one_is_refused() -> None:
    seeds = unit_of("seeds/ha")
    with pytest.raises(RateUnitError, match=r"germination of the lot \(germination_pct, 50-100"):
        seeds.check_lot({"tkw_g": 320.0}, "the lot")
    with pytest.raises(RateUnitError, match="120 % is outside 50-100 %"):
        seeds.check_lot({**MAIZE, "germination_pct": 120.0})


def test_a_count_seeder_takes_seeds_and_a_mass_implement_kilograms() -> None:
    units = RateUnits("seeds/ha", None, MAIZE)
    # DDI 11, 0.001 /m^2: 80 000 seeds/ha = 8 /m^2 = 8 000
    assert to_raw("count", 80_000, units) == 8_000
    assert from_raw("count", 8_000, units) == pytest.approx(80_000)
    # DDI 6, 1 mg/m^2: 26.95 kg/ha = 2 695 mg/m^2
    assert to_raw("mass", 80_000, units) == 2_695
    assert units.converts("mass") and not units.converts("volume")
    # without the lot a mass implement cannot take seeds
    assert not RateUnits("seeds/ha").converts("mass") and RateUnits("seeds/ha").converts("count")
