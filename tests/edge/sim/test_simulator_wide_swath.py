"""On the tractor: a 12 m plan with one headland pass on a 100 m x 190 m
field. The inner width (76 m) is not a multiple of 12 m, so the first inner swath overlaps
the ring by 8 m and its cells' real polygons (the 4 m strip the ring leaves) lie beside the
driving line. The agent looked the landing point up in those polygons, found the finished
ring cell instead, and never metered the swath (33 cells)."""

from __future__ import annotations

import numpy as np
import shapely
from fieldrx_edge.sim.simulator import SimConfig, simulate

from tests.edge.planned import X0, Y0, planned_job


def test_swath_overlapping_the_ring_is_metered() -> None:
    job, _ = planned_job(shapely.box(X0, Y0, X0 + 100, Y0 + 190), headland_passes=1, width_m=12.0)
    sw = np.asarray(job.swath)
    assert len(set(sw.tolist())) == 8
    recs: list[dict] = []
    res = simulate(job, SimConfig(seed=3, compare_runs=0), sink=recs.extend)
    metered = {r["cell_seq"] for r in recs if r["target_rate_kg_ha"] > 0}
    never = [int(s) for s in job.seq if s not in metered]
    assert never == []
    # the simulator's own landing model agrees: every cell is planned and received mass
    # (12 m at 850 kg/ha is beyond the default calibration, so accuracy is not judged here;
    # tests/system/test_wide_headland_job.py does that at 300 kg/ha)
    assert res.extra["cells"] == job.n_cells
    assert float(np.min(res.cell_m2_g)) > 0.0
