"""Soil-lab tables -> samples: German headers, decimal commas, units, coordinate systems."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fieldrx.agronomy.soil import SoilFormatError
from fieldrx.agronomy.soil_lab import (
    K_PER_K2O,
    P_PER_P2O5,
    Mapping,
    apply_mapping,
    example_lab_csv,
    nmin_to_mg_kg,
    parse_depth,
    parse_number,
    read_table,
    suggest_mapping,
)
from fieldrx.geo.crs import guess_epsg, transform_xy
from shapely.geometry import box

FIELD = box(9.90, 51.55, 9.903, 51.552)  # ~200 m x 220 m near Göttingen, UTM zone 32
NEAR = (9.9015, 51.551)


def _utm(lon: float, lat: float, epsg: int) -> tuple[float, float]:
    x, y = transform_xy(np.array([lon]), np.array([lat]), 4326, epsg)
    return float(x[0]), float(y[0])


def test_oxide_and_nmin_factors() -> None:
    # IUPAC masses: P2O5 141.94 g/mol holds 61.95 g P; K2O 94.20 g/mol holds 78.20 g K
    assert P_PER_P2O5 == pytest.approx(0.4364, abs=1e-4)
    assert K_PER_K2O == pytest.approx(0.8301, abs=1e-4)
    # 0-30 cm at 1.5 g/cm3 is 4,500 t soil/ha: 45 kg N/ha = 10 mg/kg
    assert nmin_to_mg_kg(45.0, 30.0, 1.5) == pytest.approx(10.0)


@pytest.mark.parametrize(
    ("raw", "comma", "value"),
    [("12,5", True, 12.5), ("1.234,5", True, 1234.5), ("12.5", False, 12.5), ("-3,2", True, -3.2)],
)
def test_numbers_with_decimal_commas(raw: str, comma: bool, value: float) -> None:
    assert parse_number(raw, comma) == value


def test_detection_limits_and_depth_ranges() -> None:
    with pytest.raises(ValueError, match="detection limit"):
        parse_number("<0,5", True)
    assert parse_depth("0-30", True) == 30.0
    assert parse_depth("30 - 60", True) == 60.0
    assert parse_depth("20", True) == 20.0


def test_german_lab_file_is_recognised_and_converted() -> None:
    x, y = _utm(9.9015, 51.551, 25832)
    text = (
        "Probe;Rechtswert;Hochwert;Tiefe (cm);Nmin (kg/ha);P2O5 (mg/100g);K2O (mg/100g);"
        "Humus (%);pH\n"
        f"A1;{x:.1f};{y:.1f};0-30;45;13,5;20,0;2,4;6,4\n".replace(".", ",")
    )
    t = read_table("lab.csv", text.encode("cp1252"))
    assert t.delimiter == ";" and t.decimal_comma
    m = suggest_mapping(t, NEAR)
    assert m.columns == {
        "sample_id": "Probe",
        "x": "Rechtswert",
        "y": "Hochwert",
        "depth": "Tiefe (cm)",
        "n": "Nmin (kg/ha)",
        "p": "P2O5 (mg/100g)",
        "k": "K2O (mg/100g)",
        "om": "Humus (%)",
        "ph": "pH",
    }
    assert m.units == {
        "depth": "cm",
        "n": "kg/ha",
        "p": "P2O5 mg/100g",
        "k": "K2O mg/100g",
        "om": "%",
    }
    assert m.epsg == 25832
    r = apply_mapping(t, m, FIELD)
    assert not r.errors and len(r.samples) == 1 and not r.outside
    s = r.samples[0]
    assert (s.lon, s.lat) == (pytest.approx(9.9015, abs=1e-6), pytest.approx(51.551, abs=1e-6))
    assert s.depth_cm == 30.0
    assert s.n_mg_kg == pytest.approx(10.0)  # 45 kg/ha over 0-30 cm at 1.5 g/cm3
    assert s.p_mg_kg == pytest.approx(135 * P_PER_P2O5)
    assert s.k_mg_kg == pytest.approx(200 * K_PER_K2O)
    assert s.om_g_kg == pytest.approx(24.0) and s.ph == 6.4


def test_breite_laenge_in_windows_1252_and_plain_units() -> None:
    text = "Probennummer;Breite;Länge;N (mg/kg);P (ppm);Corg (%)\nB7;51,551;9,9015;12,5;40;1,5\n"
    t = read_table("lab.txt", text.encode("cp1252"))
    assert t.encoding == "windows-1252" and "Länge" in t.header
    m = suggest_mapping(t, NEAR)
    assert m.columns["x"] == "Länge" and m.columns["y"] == "Breite" and m.epsg == 4326
    assert m.units == {"n": "mg/kg", "p": "ppm", "om": "Corg %"}
    s = apply_mapping(t, m, FIELD).samples[0]
    assert s.sample_id == "B7" and s.n_mg_kg == 12.5 and s.p_mg_kg == 40
    assert s.om_g_kg == pytest.approx(1.5 * 10 * 1.724)
    assert s.depth_cm == 20.0  # no depth column: the seed's 0-20 cm


@pytest.mark.parametrize("epsg", [25832, 31467, 4647, 32632])
def test_coordinate_systems_are_guessed_and_applied(epsg: int) -> None:
    if epsg == 4647:
        x, y = _utm(9.9015, 51.551, 25832)
        x += 32_000_000  # zone number written in front of the easting
    else:
        x, y = _utm(9.9015, 51.551, epsg)
    text = f"id,x,y,n\nS1,{x:.2f},{y:.2f},80\n"
    t = read_table("s.csv", text.encode())
    m = suggest_mapping(t, NEAR)
    expect = {25832: 25832, 31467: 31467, 4647: 4647, 32632: 25832}[epsg]
    assert m.epsg == expect
    m.epsg = epsg
    r = apply_mapping(t, m, FIELD)
    s = r.samples[0]
    tol = 1e-5 if epsg != 31467 else 5e-5  # DHDN without a grid: a few metres
    assert (s.lon, s.lat) == (pytest.approx(9.9015, abs=tol), pytest.approx(51.551, abs=tol))
    assert not r.outside


def test_guess_epsg_says_none_when_nothing_fits() -> None:
    assert guess_epsg(np.array([5.0e7]), np.array([1.0]), *NEAR) is None
    assert guess_epsg(np.array([np.nan]), np.array([np.nan]), *NEAR) is None


def test_rejected_rows_name_row_column_and_reason_and_outside_rows_are_set_apart() -> None:
    text = (
        "Probe;Breite;Länge;Nmin (kg/ha)\n"
        "P1;51,551;9,901;45\n"
        "P2;51,551;9,902;n.b.\n"  # row 3
        "P3;51,551;9,902;<5\n"  # row 4
        "P4;51,6;9,902;45\n"  # row 5: ~5 km north
        "P5;;9,902;45\n"  # row 6
    )
    t = read_table("lab.csv", text.encode("utf-8"))
    r = apply_mapping(t, suggest_mapping(t, NEAR), FIELD)
    errs = {(e.row, e.column): e.message for e in r.errors}
    assert errs[(3, "Nmin (kg/ha)")] == "expected a number, got 'n.b.'"
    assert "detection limit" in errs[(4, "Nmin (kg/ha)")]
    assert errs[(6, "Breite")].startswith("missing value")
    assert [s.sample_id for s in r.samples] == ["P1", "P4"]
    assert [s.sample_id for s in r.outside] == ["P4"]
    assert r.outside_distance_m[0] == pytest.approx(0.048 * 111_200, rel=0.01)


def test_mapping_problems_are_reported_at_the_header() -> None:
    t = read_table("lab.csv", b"Probe;Wert\nP1;3\n")
    r = apply_mapping(t, suggest_mapping(t, NEAR), FIELD)
    assert r.rejected and not r.samples
    msgs = " | ".join(e.message for e in r.errors)
    assert "no column mapped to x" in msgs and "no column mapped to a nutrient" in msgs
    assert all(e.row == 1 for e in r.errors)
    r = apply_mapping(
        t, Mapping({"x": "Wert", "y": "Nope", "n": "Wert"}, {"n": "bushels"}, 4326), FIELD
    )
    msgs = " | ".join(e.message for e in r.errors)
    assert "no column 'Nope'" in msgs and "more than one quantity" in msgs and "'bushels'" in msgs


def test_unreadable_files() -> None:
    with pytest.raises(SoilFormatError, match="save the sheet as CSV"):
        read_table("lab.xlsx", b"PK\x03\x04")
    with pytest.raises(SoilFormatError, match="used twice"):
        read_table("lab.csv", b"N;N;x\n1;2;3\n")
    with pytest.raises(SoilFormatError, match="empty"):
        read_table("lab.csv", b"\n\n")


def test_example_file_reads_back_inside_the_field() -> None:
    text, epsg = example_lab_csv(FIELD)
    assert epsg == 25832
    t = read_table("example.csv", text.encode())
    m = suggest_mapping(t, NEAR)
    assert m.epsg == 25832 and len(m.columns) == 9
    r = apply_mapping(t, m, FIELD)
    assert len(r.samples) == 9 and not r.errors and not r.outside


def test_geojson_points_go_through_the_same_mapping() -> None:
    fc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [9.9015, 51.551]},
                "properties": {"Probe": "G1", "P2O5 (mg/100g)": 10, "pH": 6.1},
            },
            {"type": "Feature", "geometry": None, "properties": {"Probe": "G2"}},
        ],
    }
    t = read_table("s.geojson", json.dumps(fc).encode())
    assert t.kind == "feature" and t.header == ["lon", "lat", "Probe", "P2O5 (mg/100g)", "pH"]
    m = suggest_mapping(t, NEAR)
    assert m.epsg == 4326 and m.units == {"p": "P2O5 mg/100g"}
    r = apply_mapping(t, m, FIELD)
    assert [s.sample_id for s in r.samples] == ["G1"]
    assert r.samples[0].p_mg_kg == pytest.approx(100 * P_PER_P2O5)
    assert {(e.kind, e.row, e.column) for e in r.errors} == {
        ("feature", 1, "lat"),
        ("feature", 1, "lon"),
    }


@pytest.mark.parametrize(
    ("header", "form"),
    [
        ("alkali_n_mg_kg", "alkali_hydrolysable"),
        ("alkali_hydrolysable_n", "alkali_hydrolysable"),
        ("Nmin (kg/ha)", "mineral"),
        ("mineral_n", "mineral"),
        ("N gesamt", "total"),
        ("total_n", "total"),
    ],
)
def test_seed_columns_and_the_n_form_are_suggested(header: str, form: str) -> None:
    """Seed 001's own soil N (alkali-hydrolysable, ``alkali_n_mg_kg``) is recognised, and
    the N form a header names becomes part of the mapping (mineral N is not the seed's N)."""
    t = read_table(
        "s.csv",
        f"sample_id,lon,lat,{header},available_p_mg_kg,ak_mg_kg\nA,9.9,51.5,80,20,90\n".encode(),
    )
    m = suggest_mapping(t, (9.9, 51.5))
    assert m.columns["n"] == header and m.n_form == form
    assert m.columns["p"] == "available_p_mg_kg" and m.columns["k"] == "ak_mg_kg"
