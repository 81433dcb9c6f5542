"""Rate units: the registry, the lot check, conversions, and each unit's ISO 11783 DDIs and
resolution against an independent data dictionary (the ``isoxml`` package's, extracted
from isobus.net)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fieldrx_edge.rateunits.registry import (
    RateUnitError,
    by_setpoint_ddi,
    convert,
    converts,
    names,
    registry_json,
    unit_of,
    units,
)
from isoxml.models.ddi_entities import DDEntity

ROOT = Path(__file__).resolve().parents[3]

# what one unit of each quantity per ha is in the data dictionary's unit per m^2
PER_HA_IN_DD_UNIT = {
    "mg/m²": 1e6 / 1e4,  # 1 kg/ha
    "mm³/m²": 1e6 / 1e4,  # 1 l/ha
    "/m²": 1 / 1e4,  # 1 count/ha
}


def test_kg_ha_is_first_and_the_default() -> None:
    assert names()[0] == "kg/ha" and unit_of(None).name == "kg/ha" and unit_of("").name == "kg/ha"
    assert {"kg/ha", "l/ha"} <= set(names())


@pytest.mark.parametrize("unit", units(), ids=lambda u: u.name)
def test_each_units_ddis_and_resolution_agree_with_the_data_dictionary(unit) -> None:
    sp, act = DDEntity.from_id(unit.ddi_setpoint), DDEntity.from_id(unit.ddi_actual)
    assert sp.name.startswith("Setpoint") and act.name.startswith("Actual")
    assert sp.unit == act.unit and sp.bit_resolution == act.bit_resolution
    assert unit.bits_per_unit == pytest.approx(PER_HA_IN_DD_UNIT[sp.unit] / sp.bit_resolution)
    assert by_setpoint_ddi(unit.ddi_setpoint) is unit


def test_unknown_unit_names_the_known_ones() -> None:
    with pytest.raises(RateUnitError, match=r"'gal/ac' is not one of \['kg/ha', 'l/ha'"):
        unit_of("gal/ac")


def test_a_lot_value_missing_or_implausible_is_named_with_its_range() -> None:
    lha = unit_of("l/ha")
    with pytest.raises(
        RateUnitError, match=r"needs the density of product 'X' \(density_kg_l, 0.05-5 kg/l\)"
    ):
        lha.check_lot({}, "product 'X'")
    with pytest.raises(RateUnitError, match=r"density_kg_l\) 12 kg/l is outside 0.05-5"):
        lha.check_lot({"density_kg_l": 12})
    with pytest.raises(RateUnitError, match="is not a number"):
        lha.check_lot({"density_kg_l": "heavy"})
    assert lha.check_lot({}, only_given=True) == {}
    assert lha.check_lot({"density_kg_l": 1.28}) == {"density_kg_l": 1.28}


def test_conversions_go_through_kg_ha_and_need_the_lot() -> None:
    kg, lha = unit_of("kg/ha"), unit_of("l/ha")
    lot = {"density_kg_l": 1.28}
    assert convert(192.0, kg, lha, lot) == pytest.approx(150.0)
    assert convert(150.0, lha, kg, lot) == pytest.approx(192.0)
    assert converts(kg, kg, None) and not converts(kg, lha, {}) and converts(kg, lha, lot)
    with pytest.raises(RateUnitError):
        convert(1.0, kg, lha, {})


def test_committed_registry_json_is_current() -> None:
    """The browser's copy (the prescription form's units and lot inputs) is current."""
    committed = (ROOT / "frontend/src/api/generated/rate-units.json").read_text()
    assert committed == registry_json(), (
        "frontend/src/api/generated/rate-units.json is stale: run scripts/gen-api.sh"
    )
