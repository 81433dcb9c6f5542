"""Management zones: classify per-cell values (imagery NDVI or an interpolated soil property)
into k zones and smooth small ones away.

Classifier: one-dimensional k-means (Lloyd's algorithm) started from the k quantile
midpoints, so it is deterministic; in one dimension its zones are contiguous value
intervals, i.e. natural breaks that minimise the within-zone sum of squares (the criterion
of Jenks' natural breaks, reached by iteration instead of Jenks' O(k n^2) table).
Zones are numbered 1..k from the lowest to the highest value.

Smoothing: cells are neighbours when their polygons touch. A connected patch of one zone
smaller than ``min_area_m2`` joins the zone it shares the most cell edges with; this is
repeated until no patch is too small (or nothing changes), so no island below the
minimum area survives unless it has no neighbour at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

MAX_ZONES = 12


class ZoneError(ValueError):
    """Bad zoning request; the message names the parameter."""


@dataclass
class Zoning:
    """Zone number per cell (0 = no data), and per zone (index z - 1) its value range."""

    labels: np.ndarray
    breaks: list[float]
    iterations: int
    merged_patches: int


def kmeans_1d(values: np.ndarray, k: int, max_iter: int = 100) -> tuple[np.ndarray, int]:
    """Zone 1..k per finite value (0 for NaN), ordered by value; and the iterations used."""
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v)
    if not 2 <= k <= MAX_ZONES:
        raise ZoneError(f"k must be 2..{MAX_ZONES}, got {k}")
    if ok.sum() < k:
        raise ZoneError(f"{int(ok.sum())} cells have a value: too few for {k} zones")
    x = np.sort(v[ok])
    centres = np.quantile(x, (np.arange(k) + 0.5) / k)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        cuts = (centres[1:] + centres[:-1]) / 2
        idx = np.searchsorted(cuts, x)
        sums = np.bincount(idx, weights=x, minlength=k)
        counts = np.bincount(idx, minlength=k)
        new = np.where(counts > 0, sums / np.maximum(counts, 1), centres)
        if np.allclose(new, centres, rtol=0, atol=1e-12):
            break
        centres = new
    cuts = (centres[1:] + centres[:-1]) / 2
    labels = np.zeros(len(v), dtype=np.int32)
    labels[ok] = np.searchsorted(cuts, v[ok]) + 1
    return labels, it


def touching_pairs(polygons: np.ndarray) -> np.ndarray:
    """(i, j) index pairs, i < j, of polygons that touch or overlap (shapely STRtree)."""
    import shapely

    polys = np.asarray(polygons, dtype=object)
    tree = shapely.STRtree(polys)
    a, b = tree.query(shapely.buffer(polys, 1e-6), predicate="intersects")
    keep = a < b
    return np.column_stack([a[keep], b[keep]])


def smooth_min_area(
    labels: np.ndarray, pairs: np.ndarray, area_m2: np.ndarray, min_area_m2: float
) -> tuple[np.ndarray, int]:
    """Merge connected same-zone patches below ``min_area_m2`` into their main neighbour."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    lab = np.asarray(labels, dtype=np.int32).copy()
    n = len(lab)
    if min_area_m2 <= 0 or n == 0 or len(pairs) == 0:
        return lab, 0
    i, j = pairs[:, 0], pairs[:, 1]
    merged = 0
    for _ in range(50):
        same = (lab[i] == lab[j]) & (lab[i] > 0)
        g = coo_matrix((np.ones(int(same.sum())), (i[same], j[same])), shape=(n, n))
        _, comp = connected_components(g, directed=False)
        comp_area = np.bincount(comp, weights=area_m2)
        small = (comp_area[comp] < min_area_m2) & (lab > 0)
        if not small.any():
            break
        # For each small patch: the neighbouring zone with the most shared edges.
        cross = lab[i] != lab[j]
        src = np.concatenate([comp[i[cross]], comp[j[cross]]])
        dst = np.concatenate([lab[j[cross]], lab[i[cross]]])
        sel = small[np.concatenate([i[cross], j[cross]])] & (dst > 0)
        if not sel.any():
            break
        key = src[sel].astype(np.int64) * (MAX_ZONES + 1) + dst[sel]
        uniq, cnt = np.unique(key, return_counts=True)
        patch, zone = uniq // (MAX_ZONES + 1), uniq % (MAX_ZONES + 1)
        order = np.lexsort((-cnt, patch))  # per patch, the most shared edges first
        patch, zone = patch[order], zone[order]
        first = np.r_[True, patch[1:] != patch[:-1]]
        target = dict(zip(patch[first].tolist(), zone[first].tolist(), strict=True))
        # Cells of each patch, and the cells across its edge.
        by_comp = np.argsort(comp, kind="stable")
        starts = np.searchsorted(comp[by_comp], np.arange(comp.max() + 2))
        a_all = np.concatenate([i[cross], j[cross]])
        b_all = np.concatenate([j[cross], i[cross]])
        nb_order = np.argsort(comp[a_all], kind="stable")
        nb_comp = comp[a_all][nb_order]
        nb_cell = b_all[nb_order]
        # Smallest patches first; a patch next to one merged this round waits for the next
        # round (two small neighbours would otherwise swap zones forever).
        touched = np.zeros(n, dtype=bool)
        changed = 0
        for p in sorted(target, key=lambda q: comp_area[q]):
            cells = by_comp[starts[p] : starts[p + 1]]
            lo, hi = np.searchsorted(nb_comp, [p, p + 1])
            if touched[nb_cell[lo:hi]].any():
                continue
            lab[cells] = target[p]
            touched[cells] = True
            changed += 1
        merged += changed
        if changed == 0:
            break
    return lab, merged


def classify_zones(
    values: np.ndarray,
    k: int,
    *,
    polygons: np.ndarray | None = None,
    area_m2: np.ndarray | None = None,
    min_area_m2: float = 0.0,
) -> Zoning:
    """k-means zones of ``values`` (NaN = no data, zone 0), smoothed to ``min_area_m2``."""
    if min_area_m2 < 0:
        raise ZoneError(f"min_area_m2 must be >= 0, got {min_area_m2}")
    labels, iters = kmeans_1d(values, k)
    merged = 0
    if min_area_m2 > 0:
        if polygons is None or area_m2 is None:
            raise ZoneError("smoothing needs the cell polygons and areas")
        labels, merged = smooth_min_area(
            labels, touching_pairs(polygons), np.asarray(area_m2, float), min_area_m2
        )
    v = np.asarray(values, dtype=float)
    breaks = []
    for z in range(1, k + 1):
        sel = labels == z
        breaks.append(float(v[sel].min()) if sel.any() else float("nan"))
    return Zoning(labels, breaks, iters, merged)


def zone_means(values: np.ndarray, labels: np.ndarray, area_m2: np.ndarray, k: int) -> np.ndarray:
    """Area-weighted mean value per zone 1..k (NaN for an empty zone)."""
    v = np.asarray(values, dtype=float)
    ok = (labels > 0) & np.isfinite(v)
    w = np.asarray(area_m2, float)[ok]
    s = np.bincount(labels[ok], weights=v[ok] * w, minlength=k + 1)[1:]
    a = np.bincount(labels[ok], weights=w, minlength=k + 1)[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(a > 0, s / a, np.nan)


def zone_cell_values(
    values: np.ndarray,
    k: int,
    *,
    polygons: np.ndarray,
    area_m2: np.ndarray,
    min_area_m2: float,
    value_name: str,
) -> tuple[np.ndarray, dict[str, Any]]:
    """A zone prescription's model input: every cell gets its zone's area-weighted mean.

    ``values`` is the per-cell property (imagery NDVI, or a soil property interpolated onto
    the cells; NaN = no data, such a cell stays NaN and gets the prescription's fallback).
    Zones are ``classify_zones`` (k-means, smoothed to ``min_area_m2``); the rate model is
    then applied to one value per zone, so each zone has exactly one rate. Returns the
    per-cell values and a description for the prescription summary: classifier, k, the
    merged patches and the zone table (zone 1 = lowest value; ``{value_name}_from`` is the
    zone's lowest cell value, ``mean_{value_name}`` its area-weighted mean).
    """
    v = np.asarray(values, dtype=float)
    area = np.asarray(area_m2, dtype=float)
    z = classify_zones(v, k, polygons=polygons, area_m2=area, min_area_m2=min_area_m2)
    means = zone_means(v, z.labels, area, k)
    per_cell = np.where(z.labels > 0, means[np.maximum(z.labels, 1) - 1], np.nan)
    table = [
        {
            "zone": i + 1,
            f"{value_name}_from": z.breaks[i],
            f"mean_{value_name}": None if np.isnan(means[i]) else float(means[i]),
            "cells": int((z.labels == i + 1).sum()),
            "area_m2": float(area[z.labels == i + 1].sum()),
        }
        for i in range(k)
    ]
    info = {
        "classifier": "kmeans_1d",
        "k": k,
        "min_area_m2": min_area_m2,
        "merged_patches": z.merged_patches,
        "zoned_value": value_name,
        "zones": table,
    }
    return per_cell, info
