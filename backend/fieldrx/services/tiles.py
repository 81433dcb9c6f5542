"""Mapbox vector tiles of plan and prescription grids straight from PostGIS (ST_AsMVT).

Two levels of detail keep tiles small for huge grids:

* detail: every cell clipped to the tile (``ST_AsMVTGeom``), used once a cell is
  at least one bin wide (bins below);
* overview: when cells are narrower than a bin (1/128 of the tile, ~2 px at
  256 px, ~4 px on a 512 px display) the cells are binned bj their bbox centre
  into 128 x 128 squares per tile; each square carries the first seq, the
  swath and, for prescriptions, the area-weighted mean rate. A 870k-cell
  grid then never puts more than 16k features in a tile.

The bin centre uses the spherical-mercator formula in SQL instead of
``ST_Transform`` per cell (cheap arithmetic on the indexed bbox). The SQL reads
the cell tables, so it lives in the cell store (``fieldrx.store.tiles``); this
module decides the level of detail.
"""

from __future__ import annotations

import math
from typing import Any

from sqlalchemy.orm import Session

from fieldrx.store import tiles as cell_tiles
from fieldrx.store.tiles import BINS, MERC_HALF

DETAIL_PX = 128  # detail once a cell is at least 1/128 of the tile wide


def tile_width_m(z: int) -> float:
    return 2 * MERC_HALF / (1 << z)


def use_overview(z: int, cell_width_m: float, lat_deg: float) -> bool:
    """True when a cell (its narrow side, in mercator metres) is under ~2 px."""
    merc = cell_width_m / max(math.cos(math.radians(lat_deg)), 1e-6)
    return merc < tile_width_m(z) / DETAIL_PX


def strides(z: int, swath_width_m: float, cell_length_m: float, lat_deg: float) -> tuple[int, int]:
    """(along, across) sampling strides for overview tiles: ~4 x 4 cells per bin remain."""
    scale = 1.0 / max(math.cos(math.radians(lat_deg)), 1e-6)
    bin_m = tile_width_m(z) / BINS
    along = max(1, int(bin_m / (4.0 * cell_length_m * scale)))
    across = max(1, int(bin_m / (4.0 * swath_width_m * scale)))
    return along, across


# the tile SQL reads the cell tables: the store's
prescription_tile = cell_tiles.cells_tile


def plan_tile(session: Session, plan_id: int, *tile: Any) -> bytes:
    """``cells_tile`` of the plan's grid alone (z, x, y, overview[, stride])."""
    return cell_tiles.cells_tile(session, plan_id, None, *tile)
