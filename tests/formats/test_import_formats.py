"""The import-format registry: detection order, and the browser's copy is current."""

from __future__ import annotations

from pathlib import Path

import pytest
from fieldrx.formats.import_formats import IMPORT_FORMATS, recognise, registry_json

ROOT = Path(__file__).resolve().parents[2]


def test_browser_copy_is_current() -> None:
    committed = (ROOT / "frontend/src/api/generated/import-formats.json").read_text()
    assert committed == registry_json(), (
        "frontend/src/api/generated/import-formats.json is stale: run scripts/gen-api.sh"
    )


@pytest.mark.parametrize(
    ("files", "kind"),
    [
        ([("export.zip", ["TASKDATA/TASKDATA.XML"])], "isoxml"),
        ([("TASKDATA.XML", []), ("GRD00001.BIN", [])], "isoxml"),
        ([("TLG00001.XML", []), ("TLG00001.BIN", [])], "timelog"),
        ([("as_applied_2026.zip", ["a.shp", "a.dbf"])], "as-applied"),
        ([("north_rx.zip", ["a.shp", "a.dbf"])], "rx-shapefile"),
        ([("north.zip", ["a.shp", "a.dbf"])], "fields"),
        ([("log.csv", [])], "as-applied"),
        ([("north.geojson", [])], "fields"),
        ([("north.kml", [])], "fields"),
        ([("notes.pdf", [])], None),
    ],
)
def test_recognise(files: list[tuple[str, list[str]]], kind: str | None) -> None:
    assert recognise(files)[0] == kind


def test_every_format_has_a_route_and_a_rule() -> None:
    for f in IMPORT_FORMATS:
        assert f.route.startswith("/") and f.rules and f.label, f.name
