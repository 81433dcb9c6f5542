"""Lag compensation: where the fertilizer will land, seed 001 sec. 2.3 (eq. 16).

Frame: local metric plane, x east, y north (e.g. UTM). Heading is the course
over ground in radians, clockwise from north, as NMEA $GPRMC gives it (in
degrees). Forward unit vector (sin h, cos h); right-hand unit vector
(cos h, -sin h).
"""

from __future__ import annotations

import math


def lag_time_s(lag_distance_m: float, speed_kmh: float) -> float:
    """Seed 001 eq. 16: T_lag = 3.6 L_lag / v (L_lag in m, v in km/h)."""
    if speed_kmh <= 0:
        raise ValueError("speed must be positive")
    return 3.6 * lag_distance_m / speed_kmh


def look_ahead(
    x: float,
    y: float,
    heading_rad: float,
    speed_m_s: float,
    lag_s: float,
    forward_offset_m: float = 0.0,
    lateral_offset_m: float = 0.0,
) -> tuple[float, float]:
    """Where a rate commanded now reaches the ground: outlet position + v * T_lag ahead.

    ``forward_offset_m`` is the outlet's position ahead of the antenna (negative
    when the outlet is behind it, the usual case for a towed implement);
    ``lateral_offset_m`` is positive to the right of the direction of travel.
    The look-ahead v * T_lag is along the heading: the machine will have moved
    that far by the time the changed rate reaches the ground.
    """
    s = math.sin(heading_rad)
    c = math.cos(heading_rad)
    fwd = forward_offset_m + speed_m_s * lag_s
    return (x + fwd * s + lateral_offset_m * c, y + fwd * c - lateral_offset_m * s)
