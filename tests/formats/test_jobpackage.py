"""Job package from cells: path order, corners, rates, checksum, size."""

import numpy as np
import pytest
from fieldrx.formats import FormatError
from fieldrx.formats.jobpackage import JobPackageSpec, build_job_package, package_etag, package_size
from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.metering import LinearCalibration, calibration_from_dict
from fieldrx_edge.protocol import ProtocolError


def _pkg(cells, field_utm, **kw):
    args = dict(
        job_id=7,
        machine_id=3,
        prescription_id=11,
        prescription_version=2,
        field_name="Test field",
        implement_width_m=2.3,
        lag_s=1.52,
        calibration=LinearCalibration(),
        controller={"name": "ladrc", "params": {"wc": 150.0}},
        speed_min_m_s=3 / 3.6,
        speed_max_m_s=2.5,
    )
    args.update(kw)
    return build_job_package(cells, field_utm, JobPackageSpec(**args))


def test_job_package_roundtrip(cells, field_utm):
    pkg = _pkg(cells, field_utm)
    back = JobPackage.from_json(pkg.to_json())  # verifies the checksum
    assert back.n_cells == len(cells) and back.seq == cells.seq.tolist()
    assert back.utm_epsg == cells.epsg and back.lag_s == 1.52
    np.testing.assert_allclose(back.rate_kg_ha, cells.rate_kg_ha, atol=0.005)
    np.testing.assert_allclose(
        np.reshape(back.corners_utm, (-1, 4, 2)), cells.corners_utm, atol=5e-4
    )
    np.testing.assert_allclose(
        np.reshape(back.corners_wgs84, (-1, 4, 2)), cells.corners_wgs84, atol=5e-9
    )
    assert calibration_from_dict(back.calibration) == LinearCalibration()
    assert back.controller.name == "ladrc" and back.controller.params == {"wc": 150.0}
    assert back.boundary_utm["type"] == "Polygon" and len(back.boundary_utm["coordinates"]) == 2
    assert package_etag(back) == f'"{pkg.checksum}"'


def test_job_package_size_and_errors(cells, field_utm):
    pkg = _pkg(cells, field_utm)
    s = package_size(pkg)
    assert s["bytes_gzip"] < s["bytes_raw"]
    assert 50 < s["bytes_per_cell_raw"] < 400 and s["bytes_per_cell_gzip"] < s["bytes_per_cell_raw"]
    with pytest.raises(ProtocolError, match="lag_s"):
        _pkg(cells, field_utm, lag_s=-1.0)
    with pytest.raises(FormatError, match="boundary_utm"):
        _pkg(cells, None)


def test_job_package_bad_machine_settings(cells, field_utm):
    with pytest.raises(FormatError, match="calibration"):
        _pkg(cells, field_utm, calibration={"kind": "table", "rpm": [1.0]})
    with pytest.raises(FormatError, match="controller"):
        _pkg(cells, field_utm, controller={"name": "pid", "gain": 3})
    table = {"kind": "table", "rpm": [6.0, 40.0], "g_per_rev": [10.0, 12.0]}
    pkg = _pkg(cells, field_utm, calibration=table)
    assert pkg.calibration["kind"] == "table" and pkg.calibration["max_rpm"] == 40.0
