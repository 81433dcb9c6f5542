"""Management zones: 1-D k-means ordered by value, min-area smoothing over touching cells."""

from __future__ import annotations

import numpy as np
import pytest
from fieldrx.agronomy.zones import (
    ZoneError,
    classify_zones,
    kmeans_1d,
    zone_cell_values,
    zone_means,
)
from shapely.geometry import box


def _grid(nx: int, ny: int, size: float = 5.0) -> np.ndarray:
    return np.array(
        [
            box(i * size, j * size, (i + 1) * size, (j + 1) * size)
            for j in range(ny)
            for i in range(nx)
        ],
        dtype=object,
    )


def test_kmeans_separates_clusters_in_value_order() -> None:
    rng = np.random.default_rng(0)
    vals = np.concatenate([rng.normal(m, 0.01, 50) for m in (0.7, 0.2, 0.45, 0.9)])
    vals[3] = np.nan
    labels, _ = kmeans_1d(vals, 4)
    assert labels[3] == 0
    for block, zone in zip(range(4), (3, 1, 2, 4), strict=True):
        seg = np.delete(labels[block * 50 : (block + 1) * 50], [3] if block == 0 else [])
        assert set(seg.tolist()) == {zone}


def test_bad_k() -> None:
    with pytest.raises(ZoneError, match="k must be"):
        kmeans_1d(np.arange(10.0), 1)
    with pytest.raises(ZoneError, match="too few"):
        kmeans_1d(np.array([0.1, np.nan, 0.2]), 3)


def test_small_island_merged_into_surrounding_zone() -> None:
    """A 10 x 10 grid of two halves, with a single odd cell (25 m2) in the low half: with
    min area 100 m2 the island joins the zone around it; the halves (1250 m2) stay."""
    polys = _grid(10, 10)
    vals = np.array([0.2 if i % 10 < 5 else 0.8 for i in range(100)])
    vals[22] = 0.8  # island
    area = np.full(100, 25.0)
    raw = classify_zones(vals, 2)
    assert raw.labels[22] == 2
    z = classify_zones(vals, 2, polygons=polys, area_m2=area, min_area_m2=100.0)
    assert z.labels[22] == 1 and z.merged_patches == 1
    assert (z.labels[[i for i in range(100) if i % 10 >= 5]] == 2).all()
    means = zone_means(vals, z.labels, area, 2)
    assert means[0] == pytest.approx((49 * 0.2 + 0.8) / 50)


def test_two_small_neighbours_do_not_swap_forever() -> None:
    polys = _grid(4, 1)
    vals = np.array([0.1, 0.5, 0.9, 0.9])
    z = classify_zones(vals, 3, polygons=polys, area_m2=np.full(4, 25.0), min_area_m2=60.0)
    assert len(set(z.labels.tolist())) == 1  # everything ends in one zone >= 60 m2


def test_zone_cell_values_gives_each_cell_its_zone_mean() -> None:
    """The zone prescription input: every cell holds its zone's area-weighted mean, no-data
    cells stay NaN, and the table names the zoned value."""
    polys = _grid(6, 2)
    vals = np.array([1.0, 1.2, 5.0, 5.4, 9.0, 9.2] * 2)
    vals[0] = np.nan
    area = np.full(12, 25.0)
    area[1] = 75.0  # weights: zone 1 is cells 1, 6, 7 -> (1.2*75 + 1.0*25 + 1.2*25) / 125
    per_cell, info = zone_cell_values(
        vals, 3, polygons=polys, area_m2=area, min_area_m2=0.0, value_name="n_mg_kg"
    )
    assert np.isnan(per_cell[0])
    assert per_cell[1] == pytest.approx((1.2 * 75 + 1.0 * 25 + 1.2 * 25) / 125)
    assert per_cell[[2, 3, 8, 9]] == pytest.approx([5.2] * 4)
    assert [z["zone"] for z in info["zones"]] == [1, 2, 3]
    assert [z["cells"] for z in info["zones"]] == [3, 4, 4]
    assert info["zones"][2]["n_mg_kg_from"] == 9.0
    assert info["zones"][0]["area_m2"] == 125.0 and info["zoned_value"] == "n_mg_kg"
