"""The job-kind registry: kinds found in their package, described completely, and every
form input's default read from the kind's own defaults."""

from __future__ import annotations

import pytest
from fieldrx_edge.jobkinds.registry import (
    DEFAULT_KIND,
    JobKind,
    UnknownKind,
    kind_of,
    kinds,
    names,
)
from fieldrx_edge.jobkinds.settings import SettingsError, validate_settings


def test_kinds_are_found_and_ordered() -> None:
    found = kinds()
    assert len(found) >= 3
    assert found[0].name == DEFAULT_KIND  # the default kind leads every list
    assert names() == tuple(k.name for k in found)
    assert len(set(names())) == len(names())
    with pytest.raises(UnknownKind, match="known"):
        kind_of("no_such_kind")


@pytest.mark.parametrize("kind", names())
def test_each_kind_is_complete(kind: str) -> None:
    k = kind_of(kind)
    assert isinstance(k, JobKind)
    d = k.describe()
    for key in ("name", "label", "noun", "source", "rates_from", "progress", "needs"):
        assert d[key], key
    assert k.rates_from in ("cells", "sensors")
    # every form input names a real setting; its default is the kind's own
    for spec in d["settings"]:
        assert spec["default"] == k.default_of(spec["path"])
        if spec["options"]:
            assert str(spec["default"]).lower() in [o.lower() for o in spec["options"]]
    if k.controllers:
        assert k.defaults["controller"]["name"] in k.controllers
    # the defaults validate as they are
    assert validate_settings(kind, {}) == (k.defaults or {})


def test_unknown_kind_is_a_settings_error() -> None:
    with pytest.raises(SettingsError) as exc:
        validate_settings("no_such_kind", {})
    assert exc.value.where == "settings.kind"
