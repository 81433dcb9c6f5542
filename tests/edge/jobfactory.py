"""Job packages for tests, built directly with numpy (no server planner needed)."""

from __future__ import annotations

from fieldrx_edge.job_package import JobPackage
from fieldrx_edge.sim.fields import RectField, field_20ha, rect_job

__all__ = ["field_20ha", "rect_job", "trial_plot", "holed_field", "big_grid"]


def trial_plot(**kw) -> JobPackage:
    """Seed 001's 35 m x 23 m trial plot: 10 swaths of 2.3 m, 5 m cells."""
    return rect_job(RectField(length_m=35.0, width_m=23.0, **kw))


def holed_field(**kw) -> JobPackage:
    """60 m x 23 m with a 20 m x 4.6 m hole (a pond) in the middle swaths."""
    return rect_job(RectField(length_m=60.0, width_m=23.0, hole=(20.0, 9.2, 40.0, 13.8), **kw))


def big_grid(n_cells: int = 100_000, **kw) -> JobPackage:
    """About ``n_cells`` cells: 1000 m long swaths of 5 m cells."""
    swaths = max(1, n_cells // 200)
    return rect_job(RectField(length_m=1000.0, width_m=swaths * 2.3, **kw))
