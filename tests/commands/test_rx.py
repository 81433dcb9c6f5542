"""`fieldrx rx` end to end in a subprocess: generated field + samples -> every export format."""

import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import shapefile as pyshp
import xmlschema
from fieldrx_edge.job_package import JobPackage
from isoxml.converter.np_grid import to_numpy_array
from isoxml.util.isoxml_io import isoxml_from_path
from pyproj import Transformer

from tests.support import scaled

XSD = "/work/shared/isoxml-xsd/ISO11783_TaskFile_V4-3.xsd"
X0, Y0 = 624000.0, 3556000.0  # UTM 49N, near seed 001's field


def _write_inputs(d: Path, n_const: float | None = None) -> tuple[Path, Path]:
    tr = Transformer.from_crs(32649, 4326, always_xy=True)
    ring = [(X0, Y0), (X0 + 90, Y0 + 8), (X0 + 84, Y0 + 60), (X0 - 4, Y0 + 52), (X0, Y0)]
    ll = [list(tr.transform(x, y)) for x, y in ring]
    field = d / "field.geojson"
    field.write_text(
        json.dumps(
            {
                "type": "FeatureCollection",
                "features": [
                    {
                        "type": "Feature",
                        "properties": {"name": "Rape 1"},
                        "geometry": {"type": "Polygon", "coordinates": [ll]},
                    }
                ],
            }
        )
    )
    rows = ["sample_id,lon,lat,depth_cm,n_mg_kg"]
    k = 0
    for x in np.arange(X0 + 4, X0 + 86, 10.0):
        for y in np.arange(Y0 + 10, Y0 + 52, 8.0):
            lon, lat = tr.transform(x, y)
            k += 1
            n = n_const if n_const is not None else 60 + 0.5 * (x - X0)
            rows.append(f"S{k},{lon:.9f},{lat:.9f},20,{n:.2f}")
    samples = d / "samples.csv"
    samples.write_text("\n".join(rows) + "\n")
    return field, samples


def _rx(*args: str, standalone: bool = False) -> tuple[int, dict]:
    """Run `fieldrx rx ...` (through fieldrx.cli) or the module's standalone parser."""
    cmd = ["-m", "fieldrx.commands.rx"] if standalone else ["-m", "fieldrx.cli", "rx"]
    proc = subprocess.run(
        [sys.executable, *cmd, *args],
        capture_output=True,
        text=True,
        timeout=scaled(120),
    )
    return proc.returncode, json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    return _write_inputs(tmp_path_factory.mktemp("rx"))


def test_rx_constant_soil_gives_worked_example_everywhere(tmp_path):
    field, samples = _write_inputs(tmp_path, n_const=100.0)
    out = tmp_path / "rx.geojson"
    rc, s = _rx(
        str(field),
        "--samples",
        str(samples),
        "--swath-width",
        "2.3",
        "--cell-length",
        "5",
        "--heading",
        "longest_edge",
        "--model",
        "nutrient_balance",
        "--target-yield",
        "2500",
        "--n-fraction",
        "0.25",
        "--interpolation",
        "idw",
        "--format",
        "geojson",
        "-o",
        str(out),
    )
    assert rc == 0, s
    fc = json.loads(out.read_text())
    assert len(fc["features"]) == s["n_cells"] > 100
    rates = {f["properties"]["rate_kg_ha"] for f in fc["features"]}
    assert rates == {700.367}  # docs/science.md worked example, in the 3 km/h..9 km/h meter range
    p = s["prescription"]
    assert p["rate_min_kg_ha"] == p["rate_max_kg_ha"] == pytest.approx(700.367, abs=1e-3)
    assert p["product_kg"] == pytest.approx(700.367 * p["area_ha"], rel=1e-6)
    assert p["n_flagged"] == 0
    # path order: seq 0..n-1 as in the file
    assert [f["properties"]["seq"] for f in fc["features"]] == list(range(s["n_cells"]))


@pytest.mark.parametrize("fmt", ["csv", "shapefile", "isoxml", "isoxml-zones", "job"])
def test_rx_every_format_reads_back(inputs, tmp_path, fmt):
    field, samples = inputs
    out = tmp_path / f"out.{fmt}"
    rc, s = _rx(
        str(field),
        "--samples",
        str(samples),
        "--interpolation",
        "cell_mean",
        "--format",
        fmt,
        "-o",
        str(out),
        "--speed-min-kmh",
        "3",
        "--speed-max-kmh",
        "9",
    )
    assert rc == 0, s
    n = s["n_cells"]
    p = s["prescription"]
    lo, hi = p["meter_range_kg_ha"]
    assert lo - 1e-6 <= p["rate_min_kg_ha"] <= p["rate_max_kg_ha"] <= hi + 1e-6
    assert p["flagged"]["no_data"] > 0  # samples every 10 m x 8 m leave many 2.3 m cells empty
    data = out.read_bytes()
    assert s["bytes"] == len(data)
    if fmt == "csv":
        lines = data.decode().splitlines()
        assert lines[0].startswith("cell_id,lat1,lon1") and len(lines) == n + 1
        rates = np.array([float(r.split(",")[-1]) for r in lines[1:]])
    elif fmt == "shapefile":
        z = zipfile.ZipFile(io.BytesIO(data))
        r = pyshp.Reader(
            shp=io.BytesIO(z.read("prescription.shp")),
            shx=io.BytesIO(z.read("prescription.shx")),
            dbf=io.BytesIO(z.read("prescription.dbf")),
        )
        assert len(r) == n
        rates = np.array([rec["RATE"] for rec in r.iterRecords()])
    elif fmt in ("isoxml", "isoxml-zones"):
        zipfile.ZipFile(io.BytesIO(data)).extractall(tmp_path)
        d = tmp_path / "TASKDATA"
        xmlschema.XMLSchema(XSD).validate(str(d / "TASKDATA.XML"))
        td, refs = isoxml_from_path(d)
        task = td.tasks[0]
        if fmt == "isoxml":
            arr = to_numpy_array(refs["GRD00001"], task.grids[0])
            vals = arr[arr > 0] / 100.0
        else:
            vals = (
                np.array(
                    [
                        t.process_data_variables[0].process_data_value
                        for t in task.treatment_zones
                        if t.polygons
                    ]
                )
                / 100.0
            )
        rates = vals
    else:
        pkg = JobPackage.from_json(data)
        assert pkg.n_cells == n and pkg.utm_epsg == s["utm_epsg"]
        assert pkg.implement_width_m == 2.3 and pkg.lag_s == 1.52
        assert s["job_package"]["bytes_per_cell_gzip"] < s["job_package"]["bytes_per_cell_raw"]
        rates = np.array(pkg.rate_kg_ha)
    assert rates.min() >= p["rate_min_kg_ha"] - 0.01
    assert rates.max() <= p["rate_max_kg_ha"] + 0.01


def test_rx_rejects_bad_samples_and_writes_nothing(inputs, tmp_path):
    field, samples = inputs
    bad = tmp_path / "bad.csv"
    bad.write_text(samples.read_text() + "X1,112.3,not-a-lat,20,90\n")
    out = tmp_path / "never.geojson"
    rc, s = _rx(str(field), "--samples", str(bad), "-o", str(out))
    assert rc == 2 and "rejected" in s["error"]
    n_rows = len(samples.read_text().splitlines())
    assert (
        s["samples"]["errors"][0]["row"] == n_rows + 1
        and s["samples"]["errors"][0]["column"] == "lat"
    )
    assert not out.exists()
    rc, s = _rx(str(field), "--samples", str(bad), "--skip-bad-rows", "-o", str(out))
    assert rc == 0 and out.exists() and s["samples"]["n_errors"] == 1
    rc, s = _rx(str(field), "--model", "uniform", "-o", str(out), standalone=True)
    assert rc == 2 and "--uniform-rate" in s["error"]
    rc, s = _rx(
        str(field), "--model", "uniform", "--uniform-rate", "700", "-o", str(out), standalone=True
    )
    assert rc == 0 and s["prescription"]["rate_min_kg_ha"] == 700.0
