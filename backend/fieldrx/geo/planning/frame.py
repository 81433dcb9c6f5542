"""The planning frame: a rotation that maps the swath direction onto +x.

Headings: ``heading_deg`` is the azimuth of the driving line, degrees clockwise from UTM
grid north in [0, 180) (0 = north-south lines, 90 = east-west lines); ``phi`` is the
math angle of the line (radians from +x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry


@dataclass(frozen=True)
class Frame:
    """Rotation about (ox, oy) that maps the swath direction (math angle phi) onto +x."""

    ox: float
    oy: float
    phi: float

    def fwd(self, c: np.ndarray) -> np.ndarray:
        """UTM -> frame coordinates, (..., 2) arrays."""
        cs, sn = math.cos(self.phi), math.sin(self.phi)
        dx = c[..., 0] - self.ox
        dy = c[..., 1] - self.oy
        return np.stack([dx * cs + dy * sn, -dx * sn + dy * cs], axis=-1)

    def inv(self, c: np.ndarray) -> np.ndarray:
        """Frame -> UTM coordinates, (..., 2) arrays."""
        cs, sn = math.cos(self.phi), math.sin(self.phi)
        x = c[..., 0]
        y = c[..., 1]
        return np.stack([x * cs - y * sn + self.ox, x * sn + y * cs + self.oy], axis=-1)

    def fwd_geom(self, g: BaseGeometry) -> BaseGeometry:
        return shapely.transform(g, self.fwd)


def azimuth_to_phi(azimuth_deg: float) -> float:
    """Azimuth (deg clockwise from north) -> math angle of the line (rad from +x)."""
    return math.radians((90.0 - azimuth_deg) % 180.0)


def phi_to_azimuth(phi: float) -> float:
    az = (90.0 - math.degrees(phi)) % 180.0
    return 0.0 if az > 180.0 - 1e-7 or az < 1e-9 else az


def frame_for(region: BaseGeometry, phi: float) -> Frame:
    c = region.centroid
    return Frame(float(c.x), float(c.y), float(phi))
