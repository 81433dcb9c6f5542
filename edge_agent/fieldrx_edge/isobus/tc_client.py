"""What the Task Controller server knows of one connected client (an implement): its
NAME and version, its object pool, the bindings of the process data the TC drives and
reads, what it reported and what was last sent to it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fieldrx_edge.isobus.ddop import Binding, DeviceDescriptor
from fieldrx_edge.isobus.j1939 import Name


@dataclass
class Client:
    address: int
    name: Name | None
    last_task_t: float
    version: int | None = None
    pool_size: int = 0
    pool: bytearray = field(default_factory=bytearray)
    ddop: DeviceDescriptor | None = None
    held: DeviceDescriptor | None = None  # the stored pool its structure label matched
    active: bool = False
    error: str = ""
    kind: str = "mass"  # or "volume"
    setpoint: Binding | None = None
    actual: Binding | None = None
    rpm: Binding | None = None
    work_state: Binding | None = None
    actual_ws: Binding | None = None
    master: Binding | None = None  # DDI 289
    section_state: Binding | None = None  # DDI 160
    rx_state: Binding | None = None  # DDI 158
    default_pd: Binding | None = None  # DDI 0xDFFF
    width_pd: Binding | None = None  # DDI 67 as process data: its value is requested
    speed: Binding | None = None
    n_sections: int = 1
    width_m: float | None = None
    sections_auto: bool = True
    rate_auto: bool = True
    measurements_sent: bool = False
    actual_rate_kg_ha: float | None = None
    actual_rpm: float | None = None
    actual_sections: list[bool] | None = None
    actual_speed_m_s: float | None = None
    values_rx: int = 0
    sent: dict[int, int] = field(default_factory=dict)  # DDI -> last value sent
    sent_t: float = -1e9

    @property
    def drivable(self) -> bool:
        return self.setpoint is not None

    @property
    def sent_rate(self) -> int | None:
        return self.sent.get(self.setpoint.ddi) if self.setpoint else None


def first_binding(bs: list[Binding]) -> Binding | None:
    return bs[0] if bs else None
