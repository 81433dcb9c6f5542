"""The job package on the wire (server -> tractor): ``JobPackage``, a job as the tractor
downloads and caches it, checksummed over its canonical JSON, with the motor controller's
settings (``protocol`` has the overview and the job kinds).

Only the standard library is used here, so the server and the agent share it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from fieldrx_edge.jobkinds.registry import DEFAULT_KIND
from fieldrx_edge.jobkinds.registry import names as kind_names
from fieldrx_edge.protocol import FORMAT_VERSION, ProtocolError
from fieldrx_edge.rateunits.registry import DEFAULT_UNIT, RateUnit, RateUnitError, unit_of


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()


@dataclass
class ControllerSettings:
    """Which motor controller the agent runs and with what parameters."""

    name: str = "ladrc"  # pid | incremental_pid | ladrc | fuzzy_pid
    params: dict[str, float] = field(default_factory=dict)
    period_s: float = 0.01  # motor loop period (100 Hz)


@dataclass
class JobPackage:
    """A job as the tractor downloads and caches it.

    ``corners_utm`` and ``corners_wgs84`` are flat lists of 8 numbers per cell
    (x0 y0 x1 y1 x2 y2 x3 y3, counter-clockwise, seed 001 Table 1), in the same
    path order as ``seq``. ``boundary_utm`` is the field boundary as GeoJSON
    Polygon/MultiPolygon coordinates in the field's UTM zone (holes included):
    the agent never applies outside it.

    The four corners are the cell's unclipped implement footprint (Table 1). At
    the field edge, around holes and in headland rings the real cell (clipped
    to the field, or between two offset curves) differs from it, and the
    rectangles of neighbouring cells overlap. Such cells also carry their real
    shape, as ragged rings in UTM, so the agent locates points in the cells the
    server planned and reports on (interior cells carry nothing extra):

    * ``shape_seq``: seq of each shaped cell, in path order (m cells);
    * ``shape_ring_offsets``: m + 1 offsets into the ring list; cell k's rings
      are rings ``shape_ring_offsets[k]:shape_ring_offsets[k + 1]`` (outer
      rings and holes alike: a point is in the cell by even-odd over all rings);
    * ``shape_offsets``: R + 1 offsets into the vertex list; ring r's vertices
      are ``shape_xy_utm[2 * shape_offsets[r]:2 * shape_offsets[r + 1]]`` as
      x y pairs, open (the first vertex is not repeated), at least 3 each.

    The shape fields are optional: a package without them (every older
    package) loads unchanged and keeps its checksum, because empty shape fields
    are left out of the canonical JSON; when present, the checksum covers them.
    """

    job_id: int
    machine_id: int
    prescription_id: int
    prescription_version: int
    field_name: str
    utm_epsg: int
    implement_width_m: float
    lag_s: float
    calibration: dict[str, Any]
    controller: ControllerSettings
    boundary_utm: dict[str, Any]
    seq: list[int]
    swath: list[int]
    rate_kg_ha: list[float]
    corners_utm: list[float]
    corners_wgs84: list[float]
    antenna_forward_m: float = 0.0  # outlet position relative to the GNSS antenna
    antenna_lateral_m: float = 0.0
    speed_min_m_s: float = 0.8
    speed_max_m_s: float = 2.5
    fix_loss_hold_s: float = 2.0  # hold the last rate this long after losing fix, then stop
    overlap_control: bool = True
    product: str = ""
    shape_seq: list[int] = field(default_factory=list)
    shape_ring_offsets: list[int] = field(default_factory=list)
    shape_offsets: list[int] = field(default_factory=list)
    shape_xy_utm: list[float] = field(default_factory=list)
    # job kind: one of fieldrx_edge.jobkinds.registry's; kind_settings are
    # the kind's validated settings (fieldrx_edge.jobkinds). Both are left out of the
    # canonical JSON when default, so prescription-map packages keep their bytes and checksum.
    kind: str = DEFAULT_KIND
    kind_settings: dict[str, Any] = field(default_factory=dict)
    # the unit of ``rate_kg_ha`` (one of ``fieldrx_edge.rateunits``: "kg/ha", or "l/ha"
    # for a liquid product's volume prescription) and the product's density in kg/l (0:
    # not known). They travel with the product so an ISOBUS TC converts between mass
    # (DDI 6) and volume (DDI 1) implements without a number typed in the cab; left out of
    # the canonical JSON when default. ``unit_lot`` holds the other lot values a unit
    # converts through (``RateUnit.lot``), left out when empty.
    rate_unit: str = DEFAULT_UNIT
    product_density_kg_l: float = 0.0
    unit_lot: dict[str, float] = field(default_factory=dict)
    format_version: int = FORMAT_VERSION
    checksum: str = ""

    @property
    def n_cells(self) -> int:
        return len(self.seq)

    def _body(self) -> dict[str, Any]:
        """Fields as a dict, without the checksum. Lists are shared, not copied (asdict would
        deep-copy ~1.6 M numbers for a 100k-cell job)."""
        body = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "checksum"}
        body["controller"] = asdict(self.controller)
        if not self.shape_seq:  # optional: absent shapes keep older packages' bytes and checksum
            for name in SHAPE_FIELDS:
                del body[name]
        if self.kind == DEFAULT_KIND and not self.kind_settings:
            del body["kind"], body["kind_settings"]
        if self.rate_unit == DEFAULT_UNIT and not self.product_density_kg_l:
            del body["rate_unit"], body["product_density_kg_l"]
        if not self.unit_lot:
            del body["unit_lot"]
        return body

    def unit(self) -> RateUnit:
        return unit_of(self.rate_unit)

    def lot(self) -> dict[str, float]:
        """The product lot's values the rate units convert through (density included)."""
        out = dict(self.unit_lot)
        if self.product_density_kg_l:
            out["density_kg_l"] = self.product_density_kg_l
        return out

    def kg_per_unit(self) -> float:
        """kg/ha in 1 of the package's rate unit/ha (the records and maps count mass)."""
        u = self.unit()
        return u.kg_per_unit(u.check_lot(self.lot(), "the job's product"))

    def in_mass(self) -> JobPackage:
        """The job as a mass meter takes it (a motor whose calibration is in g per
        revolution): its rates in kg/ha through the product lot (l/ha x density, ...), the
        package's own lot kept; ``RateUnitError`` when the lot does not say."""
        if self.unit().quantity == "mass":
            return self
        k = self.kg_per_unit()
        return dataclasses.replace(
            self, rate_kg_ha=[r * k for r in self.rate_kg_ha], rate_unit=DEFAULT_UNIT, checksum=""
        )

    def cell_shapes(self) -> dict[int, list[list[float]]]:
        """Shaped cells: path index -> rings, each a flat x y list in UTM (see class doc)."""
        if not self.shape_seq:
            return {}
        index = {s: i for i, s in enumerate(self.seq)}
        ro, vo, xy = self.shape_ring_offsets, self.shape_offsets, self.shape_xy_utm
        out: dict[int, list[list[float]]] = {}
        for k, s in enumerate(self.shape_seq):
            out[index[s]] = [xy[2 * vo[r] : 2 * vo[r + 1]] for r in range(ro[k], ro[k + 1])]
        return out

    def compute_checksum(self) -> str:
        return hashlib.sha256(_canonical(self._body())).hexdigest()

    def seal(self) -> JobPackage:
        """Validate and set the checksum; returns self for chaining."""
        self.validate()
        self.checksum = self.compute_checksum()
        return self

    def validate(self) -> None:
        n = len(self.seq)
        for name, got, want in (
            ("swath", len(self.swath), n),
            ("rate_kg_ha", len(self.rate_kg_ha), n),
            ("corners_utm", len(self.corners_utm), 8 * n),
            ("corners_wgs84", len(self.corners_wgs84), 8 * n),
        ):
            if got != want:
                raise ProtocolError(f"job package: {name} has {got} values, expected {want}")
        self._validate_shapes()
        if self.kind not in kind_names():
            raise ProtocolError(
                f"job package: kind {self.kind!r} is not one of {list(kind_names())}"
            )
        if not isinstance(self.kind_settings, dict):
            raise ProtocolError("job package: kind_settings must be an object")
        if self.implement_width_m <= 0:
            raise ProtocolError("job package: implement_width_m must be positive")
        try:
            u = self.unit()
        except RateUnitError as exc:
            raise ProtocolError(f"job package: rate_unit: {exc}") from None
        if not isinstance(self.unit_lot, dict):
            raise ProtocolError("job package: unit_lot must be an object")
        lot = self.lot()
        try:  # a value the unit converts through is checked when given (0 / absent: unknown)
            u.check_lot(lot, "the job's product", only_given=True)
        except RateUnitError as exc:
            raise ProtocolError(f"job package: {exc}") from None
        d = self.product_density_kg_l
        if not math.isfinite(d) or (d and not 0.05 <= d <= 5.0):
            raise ProtocolError(
                f"job package: product_density_kg_l {d!r} must be 0 (unknown) or 0.05-5 kg/l"
            )
        if self.lag_s < 0:
            raise ProtocolError("job package: lag_s must not be negative")
        for i, r in enumerate(self.rate_kg_ha):
            if not math.isfinite(r) or r < 0:
                raise ProtocolError(f"job package: cell {self.seq[i]} has invalid rate {r!r}")

    def _validate_shapes(self) -> None:
        m = len(self.shape_seq)
        ro, vo, xy = self.shape_ring_offsets, self.shape_offsets, self.shape_xy_utm
        if m == 0:
            if ro or vo or xy:
                raise ProtocolError("job package: shape fields given without shape_seq")
            return
        known = set(self.seq)
        if len(set(self.shape_seq)) != m or any(s not in known for s in self.shape_seq):
            raise ProtocolError("job package: shape_seq must name distinct cells of seq")
        if len(ro) != m + 1 or ro[0] != 0 or any(b <= a for a, b in zip(ro, ro[1:], strict=False)):
            raise ProtocolError(
                f"job package: shape_ring_offsets must be {m + 1} increasing offsets from 0"
            )
        n_rings = ro[-1]
        if (
            len(vo) != n_rings + 1
            or vo[0] != 0
            or any(b - a < 3 for a, b in zip(vo, vo[1:], strict=False))
        ):
            raise ProtocolError(
                f"job package: shape_offsets must be {n_rings + 1} offsets from 0,"
                " at least 3 vertices per ring"
            )
        if len(xy) != 2 * vo[-1]:
            raise ProtocolError(
                f"job package: shape_xy_utm has {len(xy)} values, expected {2 * vo[-1]}"
            )
        if not all(math.isfinite(v) for v in xy):
            raise ProtocolError("job package: shape_xy_utm has a non-finite coordinate")

    def to_json(self) -> bytes:
        if not self.checksum:
            self.seal()
        return _canonical({**self._body(), "checksum": self.checksum})

    @classmethod
    def from_json(cls, data: bytes | str | dict[str, Any], verify: bool = True) -> JobPackage:
        """Parse a package; with ``verify`` the checksum must match the content."""
        obj = json.loads(data) if isinstance(data, bytes | str) else dict(data)
        version = obj.get("format_version")
        if version != FORMAT_VERSION:
            raise ProtocolError(
                f"job package: format_version {version!r} not supported (expected {FORMAT_VERSION})"
            )
        known = {f.name for f in fields(cls)}
        unknown = set(obj) - known
        if unknown:
            raise ProtocolError(f"job package: unknown fields {sorted(unknown)}")
        obj["controller"] = ControllerSettings(**obj.get("controller", {}))
        try:
            pkg = cls(**obj)
        except TypeError as exc:
            raise ProtocolError(f"job package: {exc}") from exc
        pkg.validate()
        if verify and pkg.checksum != pkg.compute_checksum():
            raise ProtocolError("job package: checksum does not match its content")
        return pkg


SHAPE_FIELDS = ("shape_seq", "shape_ring_offsets", "shape_offsets", "shape_xy_utm")
