"""WGS84 <-> UTM (transverse Mercator, Krueger series to n^6, Karney 2011).

The agent may not depend on pyproj, yet every fix must be turned into the job's
UTM metres (the cells are in UTM). The 6th-order series is accurate to a few
nanometres inside a zone, far below GNSS noise.
"""

from __future__ import annotations

import math

_A = 6378137.0
_F = 1 / 298.257223563
_K0 = 0.9996
_E = math.sqrt(_F * (2 - _F))
_N = _F / (2 - _F)
_n = _N
_AA = _A / (1 + _n) * (1 + _n**2 / 4 + _n**4 / 64 + _n**6 / 256)
_ALPHA = (
    _n / 2
    - 2 * _n**2 / 3
    + 5 * _n**3 / 16
    + 41 * _n**4 / 180
    - 127 * _n**5 / 288
    + 7891 * _n**6 / 37800,
    13 * _n**2 / 48
    - 3 * _n**3 / 5
    + 557 * _n**4 / 1440
    + 281 * _n**5 / 630
    - 1983433 * _n**6 / 1935360,
    61 * _n**3 / 240 - 103 * _n**4 / 140 + 15061 * _n**5 / 26880 + 167603 * _n**6 / 181440,
    49561 * _n**4 / 161280 - 179 * _n**5 / 168 + 6601661 * _n**6 / 7257600,
    34729 * _n**5 / 80640 - 3418889 * _n**6 / 1995840,
    212378941 * _n**6 / 319334400,
)
_BETA = (
    _n / 2
    - 2 * _n**2 / 3
    + 37 * _n**3 / 96
    - _n**4 / 360
    - 81 * _n**5 / 512
    + 96199 * _n**6 / 604800,
    _n**2 / 48 + _n**3 / 15 - 437 * _n**4 / 1440 + 46 * _n**5 / 105 - 1118711 * _n**6 / 3870720,
    17 * _n**3 / 480 - 37 * _n**4 / 840 - 209 * _n**5 / 4480 + 5569 * _n**6 / 90720,
    4397 * _n**4 / 161280 - 11 * _n**5 / 504 - 830251 * _n**6 / 7257600,
    4583 * _n**5 / 161280 - 108847 * _n**6 / 3991680,
    20648693 * _n**6 / 638668800,
)


def zone_of_epsg(epsg: int) -> tuple[int, bool]:
    """(zone, south) for EPSG 326zz (north) / 327zz (south)."""
    if 32601 <= epsg <= 32660:
        return epsg - 32600, False
    if 32701 <= epsg <= 32760:
        return epsg - 32700, True
    raise ValueError(f"EPSG {epsg} is not a WGS84 UTM zone (326zz/327zz)")


class UtmProjection:
    """Forward and inverse projection for one UTM zone (the job's ``utm_epsg``)."""

    def __init__(self, epsg: int) -> None:
        self.epsg = epsg
        self.zone, self.south = zone_of_epsg(epsg)
        self.lon0 = math.radians(-183.0 + 6.0 * self.zone)
        self.y0 = 10_000_000.0 if self.south else 0.0

    def forward(self, lon_deg: float, lat_deg: float) -> tuple[float, float]:
        phi = math.radians(lat_deg)
        lam = math.radians(lon_deg) - self.lon0
        sphi = math.sin(phi)
        t = math.sinh(math.atanh(sphi) - _E * math.atanh(_E * sphi))
        xi_p = math.atan2(t, math.cos(lam))
        eta_p = math.atanh(math.sin(lam) / math.sqrt(1 + t * t))
        xi, eta = xi_p, eta_p
        for j, a in enumerate(_ALPHA, start=1):
            xi += a * math.sin(2 * j * xi_p) * math.cosh(2 * j * eta_p)
            eta += a * math.cos(2 * j * xi_p) * math.sinh(2 * j * eta_p)
        return 500_000.0 + _K0 * _AA * eta, self.y0 + _K0 * _AA * xi

    def inverse(self, x: float, y: float) -> tuple[float, float]:
        xi = (y - self.y0) / (_K0 * _AA)
        eta = (x - 500_000.0) / (_K0 * _AA)
        xi_p, eta_p = xi, eta
        for j, b in enumerate(_BETA, start=1):
            xi_p -= b * math.sin(2 * j * xi) * math.cosh(2 * j * eta)
            eta_p -= b * math.cos(2 * j * xi) * math.sinh(2 * j * eta)
        tau_p = math.sin(xi_p) / math.sqrt(math.sinh(eta_p) ** 2 + math.cos(xi_p) ** 2)
        lam = math.atan2(math.sinh(eta_p), math.cos(xi_p))
        tau = tau_p
        e2m = 1 - _E * _E
        for _ in range(8):  # Newton on tau (Karney 2011 eq. 19-21)
            s = math.sinh(_E * math.atanh(_E * tau / math.sqrt(1 + tau * tau)))
            ti = tau * math.sqrt(1 + s * s) - s * math.sqrt(1 + tau * tau)
            d = (
                (tau_p - ti)
                / math.sqrt(1 + ti * ti)
                * (1 + e2m * tau * tau)
                / (e2m * math.sqrt(1 + tau * tau))
            )
            tau += d
            if abs(d) < 1e-14:
                break
        return math.degrees(lam + self.lon0), math.degrees(math.atan(tau))

    def convergence_rad(self, lon_deg: float, lat_deg: float) -> float:
        """Meridian convergence: grid north minus true north, positive east of the
        central meridian (north hemisphere). Grid course = true course - convergence."""
        dl = math.radians(lon_deg) - self.lon0
        return math.atan(math.tan(dl) * math.sin(math.radians(lat_deg)))
