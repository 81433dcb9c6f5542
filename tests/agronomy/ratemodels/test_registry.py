"""The rate models' registry: every model found, aliases, and the browser's copy current."""

from pathlib import Path

import numpy as np
import pytest
from fieldrx.agronomy.ratemodels.registry import (
    RateModel,
    RateModelError,
    accepted_names,
    find_model,
    model_aliases,
    needs_input,
    param_aliases,
    rate_model,
    rate_models,
    registry_json,
)

ROOT = Path(__file__).resolve().parents[3]


def test_every_module_is_a_registered_model_in_the_listed_order() -> None:
    names = rate_models().names()
    # the default first, then the models listed before they were classes, then by name
    assert names[:3] == ("nutrient_balance", "ndvi", "uniform")
    assert list(names[3:]) == sorted(names[3:])
    for m in rate_models():
        assert isinstance(m, RateModel) and m.label and m.paper and m.params
    assert not any(rate_models().get(n).rates_in_unit for n in names[:3])  # kg/ha of product


def test_aliases_name_their_model_and_parameter() -> None:
    assert model_aliases() == {"ndvi_linear": "ndvi", "constant": "uniform"}
    assert param_aliases()["M"] == "target_yield_kg_ha"
    assert param_aliases()["rate"] == "rate_kg_ha"
    assert accepted_names() == [*rate_models().names(), "ndvi_linear", "constant"]
    assert find_model("constant") is rate_model("uniform")
    assert find_model("magic") is None


def test_unknown_model_names_the_known_ones() -> None:
    with pytest.raises(RateModelError, match=r"expected one of \['nutrient_balance', 'ndvi'"):
        rate_model("magic")
    assert needs_input("magic") and not needs_input("uniform")


def test_missing_and_unknown_parameters_are_named() -> None:
    with pytest.raises(RateModelError, match="needs per-cell values"):
        rate_model("ndvi").rates(None, {}, 1)
    with pytest.raises(RateModelError, match="bad parameter value"):
        rate_model("ndvi").rates(np.array([0.3]), {"ndvi_low": "low"}, 1)


def test_committed_registry_json_is_current() -> None:
    committed = (ROOT / "frontend/src/api/generated/rate-models.json").read_text()
    assert committed == registry_json(), (
        "frontend/src/api/generated/rate-models.json is stale: run scripts/gen-api.sh"
    )
