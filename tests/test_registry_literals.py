"""No dispatch on an export format's, a task kind's or a rate model's name outside its
own module.

Formats, task kinds and rate models each have one registry
(``formats.export.EXPORT_FORMATS``, ``formats.import_formats.IMPORT_FORMATS``,
``formats.field_import.FIELD_FILE_FORMATS``, ``tasks.kinds.TASK_KINDS``,
``agronomy.ratemodels.registry.RATE_MODELS``) whose entries are classes in their own
modules; everything else asks the registry or the entry. A comparison with one of their names
(``fmt == "shapefile"``, ``kind in ("export", "report")``, ``match`` cases) or a dict
literal keyed by two or more of them (a second list of the names) elsewhere is a second
place to change when a format or a kind is added, which is what the registries replaced.
Checked with ``ast`` over ``backend/fieldrx``; an entry's own module and its registry's
module may name it. Migrations are history (they keep the names of their time) and are
not under ``backend/``.
"""

from __future__ import annotations

import ast
import inspect
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "backend" / "fieldrx"
# (file, name): the same word meaning something else there
OTHER_MEANINGS = {
    # the object whose jobs hold evidence (field, plan, prescription), not the task kind
    ("backend/fieldrx/services/evidence.py", "prescription"),
    # an imagery kind (a single-band NDVI raster), not the NDVI rate model
    ("backend/fieldrx/api/imagery.py", "ndvi"),
    ("backend/fieldrx/imagery/ingest.py", "ndvi"),
    ("backend/fieldrx/imagery/stats.py", "ndvi"),
    ("backend/fieldrx/imagery/tiles.py", "ndvi"),
    # a column of a soil-sample file or of a machine's cell records, not the rate model
    ("backend/fieldrx/services/soil.py", "ndvi"),
    ("backend/fieldrx/fleet/ingest/validate.py", "ndvi"),
}


def registries() -> dict[str, dict[str, set[Path]]]:
    """Registry -> entry name -> the files allowed to name it (its own, the registry's)."""
    import fieldrx.tasks.work  # noqa: F401  importing it registers every task kind
    from fieldrx.agronomy.ratemodels import registry as rate_models
    from fieldrx.formats import export, field_import, import_formats
    from fieldrx.registry import Registry
    from fieldrx.tasks import kinds

    out: dict[str, dict[str, set[Path]]] = {}
    for module, reg in (
        (export, export.EXPORT_FORMATS),
        (import_formats, import_formats.IMPORT_FORMATS),
        (field_import, field_import.FIELD_FILE_FORMATS),
        (kinds, kinds.TASK_KINDS),
        (rate_models, rate_models.rate_models()),
    ):
        assert isinstance(reg, Registry)
        home = Path(inspect.getfile(module)).resolve()
        out[reg.what] = {e.name: {home, Path(inspect.getfile(type(e))).resolve()} for e in reg}
    return out


def _strings(node: ast.AST) -> list[str]:
    """The string constants ``node`` is or holds (a tuple, list or set of them)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [s for e in node.elts for s in _strings(e)]
    return []


def literals(tree: ast.AST) -> Iterator[tuple[int, str, list[str]]]:
    """(line, what, strings) of each comparison, match case and dict literal."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            ops = (ast.Eq, ast.NotEq, ast.In, ast.NotIn)
            if any(isinstance(op, ops) for op in node.ops):
                found = [s for n in (node.left, *node.comparators) for s in _strings(n)]
                yield node.lineno, "comparison", found
        elif isinstance(node, ast.MatchValue):
            yield node.lineno, "match case", _strings(node.value)
        elif isinstance(node, ast.Dict):
            keys = [s for k in node.keys if k is not None for s in _strings(k)]
            yield node.lineno, "dict keyed by", keys


def offences(path: Path, regs: dict[str, dict[str, set[Path]]]) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    out = []
    for line, what, found in literals(tree):
        for concept, names in regs.items():
            hits = sorted(
                {
                    s
                    for s in found
                    if s in names and path not in names[s] and (str(where), s) not in OTHER_MEANINGS
                }
            )
            if what == "dict keyed by" and len(hits) < 2:
                continue  # one key is a field's name (``{"plan": ...}``), not a table
            if hits:
                out.append(f"{where}:{line}: {what} {concept} name(s) {hits}")
    return out


def test_no_name_dispatch_outside_the_registries() -> None:
    regs = registries()
    found = [o for p in sorted(PACKAGE.rglob("*.py")) for o in offences(p.resolve(), regs)]
    assert not found, (
        "dispatch on a registered name outside its own module; ask the registry or the "
        "entry instead:\n" + "\n".join(found)
    )


@pytest.mark.parametrize(
    "source",
    [
        'if fmt == "shapefile":\n    pass\n',
        'ok = kind in ("export", "report")\n',
        'ext = {"geojson": ".geojson", "csv": ".csv"}\n',
        'match kind:\n    case "import":\n        pass\n',
        'if model == "uniform":\n    pass\n',
        'fill = {"nutrient_balance": True, "ndvi": False}\n',
    ],
)
def test_the_check_sees_each_form(source: str, tmp_path: Path) -> None:
    path = tmp_path / "m.py"
    path.write_text(source)
    assert offences(path, registries()) != []
