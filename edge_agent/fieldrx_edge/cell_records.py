"""Cell records on the wire (tractor -> server, uplink profile ``thin``): ``CellRecord``,
one cell's as-applied figures computed on the tractor, its checks, and the format 3 cell
batch the records travel in (``protocol`` has the overview and the format versions).

Only the standard library is used here, so the server and the agent share it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from fieldrx_edge.protocol import ALARMS, CELL_FORMAT_VERSION, INT4_MAX, ProtocolError, finite


def cell_batch_json(stream: str, stream_start: int, records_json: list[str]) -> bytes:
    """A cell batch (format 3, ``"kind": "cells"``) from records already serialised."""
    head = (
        f'{{"format":{CELL_FORMAT_VERSION},"kind":"cells","stream":"{stream}",'
        f'"stream_start":{int(stream_start)},"records":['
    )
    return (head + ",".join(records_json) + "]}").encode()


@dataclass(slots=True)
class CellRecord:
    """Uplink profile ``thin``: the as-applied figures of one cell, sent once the tractor has
    left it (and everything metered into it has landed: seed 001 eq. 16's lag).

    Computed on the tractor by the one as-applied kernel (``fieldrx_edge.asapplied``,
    seed 001 eq. 16-18) over the full 10 Hz log, which stays on the tractor, so the
    server's report from these records equals the report from the full log:

    * ``mass_g``: metered mass that landed in the cell (eq. 16-17: flow from the shaft
      speed over each fix period, landing T_lag later, antenna offset ahead); on the
      record with ``cell_seq`` null, the mass that landed in no cell;
    * ``driven_m``: the cell's driven length (eq. 17's v t, ``asapplied.driven_length``);
    * ``n_fixes``, ``worked_s``, ``t_entry``/``t_exit``, the means: the fixes whose own
      cell (the one the agent metered for) is this one, implement down; their fix
      periods, first/last fix time, mean speed and mean target/applied rate;
    * ``flags``: the alarms raised in those fixes.

    A cell can get more than one record (re-entered later, or a little mass landing
    after its record left): the server adds them up.
    """

    machine_id: int
    seq: int
    job_id: int
    t_entry: float
    t_exit: float
    cell_seq: int | None = None
    n_fixes: int = 0
    worked_s: float = 0.0
    mass_g: float = 0.0
    driven_m: float | None = None
    mean_speed_m_s: float | None = None
    mean_target_rate_kg_ha: float | None = None
    mean_applied_rate_kg_ha: float | None = None
    flags: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {f: getattr(self, f) for f in CELL_FIELDS}

    @classmethod
    def from_dict(cls, obj: dict[str, Any]) -> CellRecord:
        """Parse and validate one cell record; ``ProtocolError`` names the offending field."""
        if not isinstance(obj, dict):
            raise ProtocolError("cell record is not a JSON object")
        unknown = set(obj) - _CELL_FIELD_SET
        if unknown:
            raise ProtocolError(f"unknown fields {sorted(unknown)}")
        for name in ("machine_id", "seq", "job_id", "t_entry", "t_exit"):
            if name not in obj:
                raise ProtocolError(f"missing required field '{name}'")
        rec = cls(**obj)
        rec.validate()
        return rec

    def validate(self) -> None:
        for name in ("machine_id", "seq", "job_id"):
            v = getattr(self, name)
            if type(v) is not int or v < 1:
                raise ProtocolError(f"{name} must be a positive integer, got {v!r}")
        c = self.cell_seq
        if c is not None and (type(c) is not int or not -INT4_MAX <= c <= INT4_MAX):
            raise ProtocolError(f"cell_seq must be an integer or null, got {c!r}")
        if type(self.n_fixes) is not int or not 0 <= self.n_fixes <= INT4_MAX:
            raise ProtocolError(f"n_fixes must be a non-negative integer, got {self.n_fixes!r}")
        for name in ("t_entry", "t_exit"):
            v = getattr(self, name)
            if not finite(v) or v <= 0:
                raise ProtocolError(f"{name} must be a positive unix time in seconds, got {v!r}")
        if self.t_exit < self.t_entry:
            raise ProtocolError(f"t_exit {self.t_exit!r} is before t_entry {self.t_entry!r}")
        for name in ("worked_s", "mass_g"):
            v = getattr(self, name)
            if not finite(v) or v < 0:
                raise ProtocolError(f"{name} must be a finite number >= 0, got {v!r}")
        for name in _CELL_OPTIONAL:
            v = getattr(self, name)
            if v is not None and (not finite(v) or v < 0):
                raise ProtocolError(f"{name} must be a finite number >= 0 or null, got {v!r}")
        if not isinstance(self.flags, list) or any(a not in ALARMS for a in self.flags):
            raise ProtocolError(f"flags must be a list of {list(ALARMS)}, got {self.flags!r}")


CELL_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(CellRecord))
_CELL_FIELD_SET = frozenset(CELL_FIELDS)
_CELL_OPTIONAL = (
    "driven_m", "mean_speed_m_s", "mean_target_rate_kg_ha", "mean_applied_rate_kg_ha",
)  # fmt: skip


def sanitize_cell_record(rec: dict[str, Any]) -> list[str]:
    """``sanitize_record`` for cell records (the queue runs it before storing one): they are
    computed by the agent itself, so anything wrong is a bug; say what, never block."""
    try:
        CellRecord.from_dict(rec).validate()
    except (ProtocolError, TypeError) as exc:
        return [f"drop: {exc}"]
    return []
