"""The API offers exactly the rate models' registry (agronomy.ratemodels)."""

from fieldrx.agronomy.ratemodels.registry import accepted_names, rate_models
from fieldrx.app import create_app


def test_openapi_enum_is_the_registry() -> None:
    doc = create_app().openapi()
    model = doc["components"]["schemas"]["PrescriptionIn"]["properties"]["model"]
    assert model["enum"] == accepted_names()
    assert model["default"] == rate_models().names()[0]
    for m in rate_models():
        assert m.name in model["description"]
