"""The import-format registry: what FieldRx reads, which route takes it, how it is recognised.

Each import format is one class below, registered with ``IMPORT_FORMATS``: its name (the
browser's import kind), label, the API route that takes it, and its recognition rules.
Recognition looks at the uploaded files' base names (and, for a zip, the names inside
it): the rules of every format are tried together by ``priority`` (the detection order,
lowest first), each a regular expression over an upper-case base name, checked on any
file or member (``scope = "any"``) or on the first chosen file only (``"first"``),
optionally narrowed by a pattern over the first file's lower-case name (a zipped
Shapefile can be any of three things: its name decides the guess, the user confirms).

``recognise`` is the detection; ``registry_json`` is what ``scripts/gen-api.sh``
writes to ``frontend/src/api/generated/import-formats.json``, from which the browser
builds its import menu and runs the same detection. The field-boundary files that
``/fields/import`` reads are ``formats.field_import.FIELD_FILE_FORMATS``.
"""

from __future__ import annotations

import json
import re
from dataclasses import asdict, dataclass

from fieldrx.registry import Registry


@dataclass(frozen=True)
class Rule:
    """One way of recognising a format (see the module docstring)."""

    priority: int
    pattern: str
    why: str
    scope: str = "any"  # "any" file or zip member, or the "first" chosen file
    file_name: str = ""  # and the first file's lower-case name matches this


class ImportFormat:
    name: str = ""
    label: str = ""
    route: str = ""  # under /api/v1
    rules: tuple[Rule, ...] = ()


IMPORT_FORMATS: Registry[ImportFormat] = Registry("import format")

SHAPEFILE_WHY = "holds a Shapefile: say what it is"


@IMPORT_FORMATS.register
class FieldBoundaries(ImportFormat):
    name = "fields"
    label = "Field boundaries (GeoJSON, KML, Shapefile)"
    route = "/fields/import"
    rules = (
        Rule(32, r"\.SHP$", SHAPEFILE_WHY),
        Rule(50, r"\.(GEOJSON|JSON|KML)$", "field boundaries", scope="first"),
    )


@IMPORT_FORMATS.register
class Taskdata(ImportFormat):
    name = "isoxml"
    label = "ISO 11783-10 TASKDATA (farms, fields, prescriptions, TimeLogs)"
    route = "/imports/isoxml"
    rules = (Rule(10, r"^TASKDATA\.XML$", "holds TASKDATA.XML"),)


@IMPORT_FORMATS.register
class PrescriptionShapefile(ImportFormat):
    name = "rx-shapefile"
    label = "Prescription Shapefile (rates per zone)"
    route = "/imports/prescription-shapefile"
    rules = (
        Rule(
            31,
            r"\.SHP$",
            SHAPEFILE_WHY,
            file_name=r"(^|[^a-z])rx([^a-z]|$)|rate|presc|vra|zones?",
        ),
    )


@IMPORT_FORMATS.register
class TimeLogs(ImportFormat):
    name = "timelog"
    label = "ISO 11783-10 TimeLogs (as-applied records)"
    route = "/imports/timelog"
    rules = (Rule(20, r"^TLG\d+\.XML$", "holds TLGxxxxx.XML TimeLogs"),)


@IMPORT_FORMATS.register
class AsAppliedTable(ImportFormat):
    name = "as-applied"
    label = "As-applied table (CSV or Shapefile records)"
    route = "/imports/as-applied-table"
    rules = (
        Rule(30, r"\.SHP$", SHAPEFILE_WHY, file_name=r"applied|asapplied|as_applied|coverage|log"),
        Rule(40, r"\.(CSV|TXT)$", "a table of records", scope="first"),
    )


def detection_order() -> list[tuple[Rule, ImportFormat]]:
    """Every format's rules, lowest priority first (the order they are tried in)."""
    rules = [(rule, fmt) for fmt in IMPORT_FORMATS for rule in fmt.rules]
    return sorted(rules, key=lambda rf: rf[0].priority)


def _base(name: str) -> str:
    return re.split(r"[\\/]", name)[-1].upper()


def recognise(files: list[tuple[str, list[str]]]) -> tuple[str | None, str]:
    """(format name or None, why) of an upload: each file's name and a zip's member names.
    The browser runs the same rules (``frontend/src/lib/importKind.ts``)."""
    names = [_base(n) for name, members in files for n in (name, *members)]
    first_name = files[0][0] if files else ""
    for rule, fmt in detection_order():
        pool = [_base(first_name)] if rule.scope == "first" else names
        if not any(re.search(rule.pattern, n) for n in pool):
            continue
        if rule.file_name and not re.search(rule.file_name, first_name.lower()):
            continue
        return fmt.name, rule.why
    listed = ", ".join(name for name, _ in files) or "nothing"
    return None, f"{listed}: not a format FieldRx reads"


def registry_json() -> str:
    """The registry as the browser reads it (``scripts/gen-api.sh`` writes it)."""
    items = [
        {
            "name": f.name,
            "label": f.label,
            "route": f.route,
            "rules": [asdict(r) for r in f.rules],
        }
        for f in IMPORT_FORMATS
    ]
    return json.dumps({"import_formats": items}, indent=2) + "\n"
