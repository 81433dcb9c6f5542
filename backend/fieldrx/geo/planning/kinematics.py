"""Stage: the machine that drives the plan.

A tractor with a mounted spreader or seeder turns on a circle of 4-8 m radius; it cannot
jump sideways by one working width at the end of a swath. ``Machine`` carries what the
turn stage needs: the minimum turning radius, whether the machine may reverse (for
fishtail / K-turns), and the speeds that turn path lengths into times for the metrics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import PlanningError

DEFAULT_TURN_RADIUS_M = 6.0
# The one default of headland passes (API, CLI, UI through the OpenAPI document): none, so a
# plan covers the field boundary to boundary; its metrics say how many passes the machine's
# turns need (``required_headland_passes``) and warn when the plan has fewer.
DEFAULT_HEADLAND_PASSES = 0
MAX_TURN_RADIUS_M = 50.0


@dataclass(frozen=True)
class Machine:
    """Kinematics of the tractor + implement.

    ``turn_speed_m_s`` (2 m/s = 7.2 km/h) is the speed in headland turns,
    ``reverse_speed_m_s`` the speed when reversing and ``cusp_s`` the time lost at each
    change of driving direction (stop, shuttle, start). They only feed the turn time
    metric and the choice between a bulb turn and a fishtail.
    """

    turn_radius_m: float = DEFAULT_TURN_RADIUS_M
    reverse: bool = False
    turn_speed_m_s: float = 2.0
    reverse_speed_m_s: float = 1.0
    cusp_s: float = 3.0

    def __post_init__(self) -> None:
        r = self.turn_radius_m
        if not isinstance(r, int | float) or not math.isfinite(r) or not 0 < r <= MAX_TURN_RADIUS_M:
            raise PlanningError(f"turn_radius_m must be > 0 and <= {MAX_TURN_RADIUS_M} m, got {r}")
        for name in ("turn_speed_m_s", "reverse_speed_m_s"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise PlanningError(f"{name} must be > 0, got {v}")

    def time_s(self, forward_m: float, reverse_m: float = 0.0, cusps: int = 0) -> float:
        """Time to drive a turn of ``forward_m`` forward and ``reverse_m`` in reverse."""
        return (
            forward_m / self.turn_speed_m_s
            + reverse_m / self.reverse_speed_m_s
            + cusps * self.cusp_s
        )
