"""Interpolation of soil samples onto cells."""

import numpy as np
import pytest
import shapely
from fieldrx.agronomy.cells import CellTable
from fieldrx.agronomy.interpolate import (
    InterpolationError,
    cell_mean,
    idw,
    interpolate_to_cells,
    kriging,
)
from pykrige.ok import OrdinaryKriging

EPSG = 32650  # UTM 50N (seed 001 is near 112.3 E, 32.1 N -> zone 49; any zone works)


def _grid(n_swaths=4, n_per=3):
    return CellTable.rectangle(EPSG, 500000.0, 3550000.0, n_swaths, n_per, 2.3, 5.0)


def test_cell_mean_five_point_sampling():
    cells = _grid(2, 2)
    # five samples in cell 0 (centre + 4 corners) with values 1..5, nothing else
    c0 = cells.corners_utm[0]
    pts = np.vstack([cells.centroids_utm[0], c0])
    vals = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    res = cell_mean(cells.polygons_utm, pts, vals)
    assert res.values[0] == pytest.approx(3.0)
    # corner samples are shared with the touching cells (the seed samples each cell's corners)
    for i in range(1, len(cells)):
        shared = [
            v
            for p, v in zip(c0, vals[1:], strict=True)
            if shapely.intersects(cells.polygons_utm[i], shapely.Point(p))
        ]
        if shared:
            assert res.values[i] == pytest.approx(np.mean(shared))
        else:
            assert np.isnan(res.values[i]) and res.no_data[i]


def test_cell_mean_empty_cells_are_no_data():
    cells = _grid(3, 3)
    res = cell_mean(cells.polygons_utm, cells.centroids_utm[:2], np.array([10.0, 20.0]))
    np.testing.assert_allclose(res.values[:2], [10.0, 20.0])
    assert res.no_data[2:].all() and not res.no_data[:2].any()


def test_idw_exact_at_sample_points_and_hand_value():
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 100, size=(30, 2))
    z = rng.uniform(50, 150, size=30)
    res = idw(xy, xy, z, power=2.0)
    np.testing.assert_allclose(res.values, z, rtol=0, atol=1e-12)
    # two samples at distance 1 and 3 from the target: weights 1 and 1/9
    r = idw(np.array([[1.0, 0.0]]), np.array([[0.0, 0.0], [4.0, 0.0]]), np.array([10.0, 20.0]))
    assert r.values[0] == pytest.approx((10 * 1 + 20 / 9) / (1 + 1 / 9))


def test_idw_radius_gives_no_data():
    xy = np.array([[0.0, 0.0]])
    res = idw(np.array([[1.0, 0.0], [100.0, 0.0]]), xy, np.array([7.0]), radius_m=10.0)
    assert res.values[0] == 7.0 and np.isnan(res.values[1])
    assert res.no_data.tolist() == [False, True]
    with pytest.raises(InterpolationError, match="power"):
        idw(xy, xy, np.array([1.0]), power=0)


def _field_samples(n=25, seed=3):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 200, size=(n, 2))
    z = 80 + 0.2 * xy[:, 0] + 10 * np.sin(xy[:, 1] / 40) + rng.normal(0, 2, n)
    return xy, z


def test_kriging_exact_at_samples_and_reports_loo_rmse():
    xy, z = _field_samples()
    res = kriging(xy, xy, z, variogram_model="spherical")
    np.testing.assert_allclose(res.values, z, atol=1e-6)
    assert res.info["loo_rmse"] > 0
    # brute force: refit n systems with the same variogram, predict the left-out sample
    params = res.info["variogram_parameters"]
    o = xy - xy.mean(axis=0)
    resid = []
    for i in range(len(z)):
        m = np.arange(len(z)) != i
        ok = OrdinaryKriging(
            o[m, 0], o[m, 1], z[m], variogram_model="spherical", variogram_parameters=params
        )
        zi, _ = ok.execute("points", o[i : i + 1, 0], o[i : i + 1, 1])
        resid.append(z[i] - float(zi[0]))
    assert res.info["loo_rmse"] == pytest.approx(np.sqrt(np.mean(np.square(resid))), rel=1e-6)


@pytest.mark.parametrize("model", ["linear", "gaussian", "exponential"])
def test_kriging_variogram_models_selectable(model):
    xy, z = _field_samples(20, seed=5)
    t = np.array([[100.0, 100.0], [1000.0, 1000.0]])
    res = kriging(t, xy, z, variogram_model=model, max_distance_m=300.0)
    assert res.info["variogram_model"] == model
    assert np.isfinite(res.values[0]) and min(z) - 20 < res.values[0] < max(z) + 20
    assert res.no_data.tolist() == [False, True]


def test_kriging_errors():
    xy, z = _field_samples(10)
    with pytest.raises(InterpolationError, match="variogram"):
        kriging(xy, xy, z, variogram_model="cubic")
    with pytest.raises(InterpolationError, match="at least 3"):
        kriging(xy[:2], xy[:2], z[:2])


@pytest.mark.slow
def test_dispatch_and_large_grid_is_vectorised():
    # 100k cells: every method must finish quickly (no per-cell Python loops)
    cells = CellTable.rectangle(EPSG, 500000.0, 3550000.0, 200, 500, 2.3, 5.0)
    assert len(cells) == 100_000
    rng = np.random.default_rng(0)
    lo = cells.centroids_utm.min(axis=0)
    hi = cells.centroids_utm.max(axis=0)
    xy = rng.uniform(lo, hi, size=(200, 2))
    z = rng.uniform(50, 150, 200)
    for method, params in (
        ("cell_mean", {}),
        ("idw", {"power": 2, "radius_m": 60}),
        ("kriging", {"variogram_model": "exponential"}),
    ):
        res = interpolate_to_cells(method, cells.polygons_utm, cells.centroids_utm, xy, z, **params)
        assert res.values.shape == (100_000,)
        assert res.no_data.sum() == np.isnan(res.values).sum()
    with pytest.raises(InterpolationError, match="unknown interpolation"):
        interpolate_to_cells("nearest", cells.polygons_utm, cells.centroids_utm, xy, z)


def test_default_search_distance_leaves_far_cells_without_data():
    """IDW spread four samples over the whole field (no_data 0)."""
    from fieldrx.agronomy.interpolate import (
        MIN_SEARCH_RADIUS_M,
        default_search_radius_m,
        interpolate_to_cells,
    )

    pts = np.array([[0.0, 0.0], [40.0, 0.0], [0.0, 40.0], [40.0, 40.0]])
    assert default_search_radius_m(pts) == pytest.approx(120.0)  # 3 x 40 m spacing
    assert default_search_radius_m(pts[:1]) == MIN_SEARCH_RADIUS_M
    assert default_search_radius_m(pts / 10) == MIN_SEARCH_RADIUS_M  # dense: the floor
    targets = np.array([[20.0, 20.0], [100.0, 20.0], [1000.0, 20.0]])
    for method in ("idw", "kriging"):
        res = interpolate_to_cells(method, np.array([None] * 3), targets, pts, [1.0, 2.0, 3.0, 4.0])
        assert res.no_data.tolist() == [False, False, True], method
        assert res.info["search_distance_m"] == pytest.approx(120.0)
        assert res.info["search_distance_default"] is True
    unlimited = interpolate_to_cells(
        "idw", np.array([None] * 3), targets, pts, [1.0, 2.0, 3.0, 4.0], radius_m=None
    )
    assert not unlimited.no_data.any()
