"""The one cell store: plan cells and prescription rates in PostgreSQL.

* ``codec``: the binary COPY codec (numpy row layouts, EWKB, varchar[]) and the
  packed reads that mirror it; also the declared-type row path for telemetry;
* ``cells``: a plan's cells (one partition per plan, binary COPY, packed reads
  back into :class:`fieldrx.geo.cells.Cells`);
* ``rates``: a prescription version's per-cell rates and flags;
* ``tiles``: the cell layers of the map (Mapbox vector tiles from PostGIS).

Services, fleet reports, tiles and exports read and write cells only through
this package; nothing else knows how ``plan_cells`` / ``prescription_rates`` are laid
out.
"""

from fieldrx.store.cells import (
    driver_connection,
    load_cells,
    load_seq_area,
    partition_name,
    write_plan_cells,
)
from fieldrx.store.rates import load_rates, write_rates

__all__ = [
    "driver_connection",
    "load_cells",
    "load_rates",
    "load_seq_area",
    "partition_name",
    "write_plan_cells",
    "write_rates",
]
