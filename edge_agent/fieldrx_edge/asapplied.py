"""As-applied kernel (seed 001 eq. 16-18), pure numpy: shared by the agent and the server.

So far it holds the time integration of telemetry: how long each record's
metering lasted. The rest of the kernel (landing point, driven length) still
lives in ``fieldrx.fleet.reports`` and ``fieldrx_edge.sim.simulator``
(DESIGN.md names this module as their future single home).

A telemetry record describes one GNSS fix; its time ``t`` is the fix time and
its ``fix_period_s`` the receiver's fix interval (``protocol.TelemetryRecord``).
Mass metered during a record's period is flow * period (seed 001 eq. 17:
M = q t, q the metered flow). Integrating over the gap to the next record's time
instead makes the mass depend on how the records were stamped: a producer that
stamps 0.01 s apart what are 0.1 s fixes reports a tenth of the mass (issue 11).
"""

from __future__ import annotations

import numpy as np

MISSED_FIX = 1.5  # a gap beyond this many fix periods means fixes were missed


def fix_periods(
    t: np.ndarray, period: np.ndarray | None = None, max_gap_s: float = 2.0
) -> np.ndarray:
    """Duration (s) each record's metering state lasted, records sorted by time.

    Records without a fix period (format 1) last until the next record's time,
    0 across a gap longer than ``max_gap_s`` (an outage: nothing is known about
    it); the last record lasts the median gap. A record that carries its fix
    period (finite, > 0) lasts that period, whatever the spacing of the time
    stamps (jitter, or stamps squeezed together), except where the next record
    comes clearly later (more than ``MISSED_FIX`` periods, up to ``max_gap_s``):
    fixes were missed there (the agent holds the last rate through a short loss
    of fix) and the gap is the duration, as for records without a period.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    if n == 0:
        return np.zeros(0)
    gaps = np.diff(t)
    typical = float(np.median(gaps)) if len(gaps) else 0.0
    dts = np.append(gaps, typical)
    dts = np.where(dts > max_gap_s, 0.0, np.maximum(dts, 0.0))
    if period is not None:
        p = np.asarray(period, dtype=float)
        known = np.isfinite(p) & (p > 0)
        missed = known & (dts > MISSED_FIX * np.where(known, p, 0.0))
        dts = np.where(known & ~missed, p, dts)
    return dts


def metered_mass_g(flow_g_s: np.ndarray, dts: np.ndarray) -> np.ndarray:
    """Grams metered in each record's period: trapezoid between this record's flow and the
    next one's (the shaft speed moves between fixes), the last record at its own flow."""
    flow = np.asarray(flow_g_s, dtype=float)
    nxt = np.append(flow[1:], flow[-1:]) if len(flow) else flow
    return 0.5 * (flow + nxt) * np.asarray(dts, dtype=float)
