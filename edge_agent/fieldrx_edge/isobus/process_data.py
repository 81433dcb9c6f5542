"""ISO 11783-10 process data messages (PGN 0xCB00) and the DDIs FieldRx uses.

Every process data message is 8 bytes:

    byte 0  bits 0-3 command, bits 4-7 element number bits 0-3
    byte 1  element number bits 4-11
    bytes 2-3  DDI (little-endian)
    bytes 4-7  value (int32, little-endian)

Commands: 0x0 technical capabilities, 0x1 device descriptor, 0x2 request value, 0x3 value,
0x4 measurement time interval (ms), 0x5 measurement distance interval (mm), 0x6/0x7
measurement min/max threshold, 0x8 measurement change threshold, 0x9 peer control
assignment, 0xA set value and acknowledge, 0xD process data acknowledge, 0xE TC status
(broadcast), 0xF client task. Technical capabilities and device descriptor messages use
the high nibble as a sub-command instead of the element number:

    TC status       0xFE | 0xFF 0xFF 0xFF | status bits | command source addr | command | 0xFF
    request version 0x00 | 0xFF x7;   version 0x10 | version | 0xFF | options | 0x00 |
                    booms | sections | position-control channels
    structure label request 0x01 / reply 0x11; localization label request 0x21 / reply
    0x31; request object-pool transfer 0x41 | size (4) / reply 0x51 | 0 ok, 1 no memory;
    object-pool transfer 0x61 | pool bytes / reply 0x71 | errors | size (4);
    activate 0x81 | 0xFF (0x00 deactivates) / reply 0x91 | activation errors |
    parent of faulty object (2) | faulty object (2) | pool errors; delete 0xA1 / 0xB1
    PDACK           0x?D | element | DDI (2) | error bits | 0xF0 | command acknowledged
    client task     0xFF | 0xFF 0xFF 0xFF | status bits (bit 0 task active) | 0 0 0

Version message options (byte 3): bit 0 documentation, bit 1 TC-GEO without position-based
control, bit 2 TC-GEO with position-based control, bit 3 peer control assignment, bit 4
implement section control; a client announces in it what its pool offers (section control
when it has a settable setpoint condensed work state and section elements), bytes 5-6 its
booms and sections for section control.

Activation response byte 1 (ISO 11783-10 B.5.17): bit 0 errors in the DDOP, bit 1 TC out of
memory, bit 2 any other error, bit 3 a different DDOP with the same structure label.

Language command (ISO 11783-7 sec. 8.5.2, PGN 0xFE0F, broadcast; provided on request by a
TC, ISO 11783-10 Annex B connection procedure): bytes 0-1 language code (ISO 639), byte 2
bits 7-6 decimal symbol (01 point) and 5-4 time format (00 24 h), byte 3 date format (0
ddmmyyyy), byte 4 distance / area / volume / mass units, byte 5 temperature / pressure /
force / generic units (00 metric each), bytes 6-7 reserved. A DDOP's localization label
is the first 7 bytes of the language command it was written for.

Working set master (ISO 11783-7, PGN 0xFE0D): byte 0 number of working-set members.
Machine selected speed (ISO 11783-7, PGN 0xF022): bytes 0-1 speed (1 mm/s), bytes 2-5
distance (1 mm), byte 6 exit code, byte 7 bits 0-1 direction, 2-4 source, 5-6 limit status.

Public descriptions used: AgIsoStack++ ``isobus_task_controller_server.cpp`` (status,
version, label, transfer, activation and PDACK payloads; element-number packing) and
``isobus_task_controller_server.hpp`` (command and sub-command enums),
``isobus_speed_distance_messages.cpp`` (machine selected speed decoding); DDIs and
resolutions from the isoxml package's copy of the isobus.net data dictionary.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

CMD_TECHNICAL = 0x0
CMD_DEVICE_DESCRIPTOR = 0x1
CMD_REQUEST_VALUE = 0x2
CMD_VALUE = 0x3
CMD_MEAS_TIME = 0x4
CMD_MEAS_DISTANCE = 0x5
CMD_MEAS_MIN = 0x6
CMD_MEAS_MAX = 0x7
CMD_MEAS_CHANGE = 0x8
CMD_SET_VALUE_ACK = 0xA
CMD_PDACK = 0xD
CMD_STATUS = 0xE
CMD_CLIENT_TASK = 0xF

# technical capabilities sub-commands
TECH_REQUEST_VERSION = 0x0
TECH_VERSION = 0x1
# device descriptor sub-commands
DD_REQ_STRUCTURE = 0x0
DD_STRUCTURE = 0x1
DD_REQ_LOCALIZATION = 0x2
DD_LOCALIZATION = 0x3
DD_REQ_TRANSFER = 0x4
DD_REQ_TRANSFER_RESP = 0x5
DD_TRANSFER = 0x6
DD_TRANSFER_RESP = 0x7
DD_ACTIVATE = 0x8
DD_ACTIVATE_RESP = 0x9
DD_DELETE = 0xA
DD_DELETE_RESP = 0xB

# DDIs (isobus.net data dictionary; unit = resolution of one bit)
DDI_SETPOINT_VOLUME_PER_AREA = 1  # 0.01 mm^3/m^2
DDI_ACTUAL_VOLUME_PER_AREA = 2  # 0.01 mm^3/m^2
DDI_SETPOINT_MASS_PER_AREA = 6  # 1 mg/m^2
DDI_ACTUAL_MASS_PER_AREA = 7  # 1 mg/m^2
DDI_ACTUAL_WORKING_WIDTH = 67  # mm
DDI_OFFSET_X = 134  # mm
DDI_OFFSET_Y = 135  # mm
DDI_ACTUAL_WORK_STATE = 141
DDI_PRESCRIPTION_CONTROL_STATE = 158  # 0 manual, 1 auto, 2 error, 3 not available
DDI_SECTION_CONTROL_STATE = 160  # 0 manual, 1 auto, 2 error, 3 not available
DDI_SETPOINT_WORK_STATE = 289  # the element's master on/off set by the TC
DDI_REQUEST_DEFAULT_PD = 0xDFFF  # request value on it: the client sends its default set
DDI_ACTUAL_CONDENSED_WORK_STATE = 161  # sections 1-16, 2 bits each
DDI_SETPOINT_CONDENSED_WORK_STATE = 290  # sections 1-16, 2 bits each
DDI_ACTUAL_REVOLUTIONS = 390  # 0.0001 r/min
DDI_ACTUAL_SPEED = 397  # mm/s

# 1 kg/ha = 1e6 mg / 1e4 m^2 = 100 mg/m^2 (the rate ECU's mass setpoint; every rate
# unit's DDIs and resolution are in fieldrx_edge.rateunits)
MG_M2_PER_KG_HA = 100.0
RPM_BITS = 10_000.0

TC_VERSION = 4  # ISO 11783-10 version 4 (second edition, final draft)
SERVER_OPTION_TCGEO_NO_PBC = 0x02
SERVER_OPTION_SECTION_CONTROL = 0x10

SERVER_OPTION_DOCUMENTATION = 0x01
SERVER_OPTION_PEER_CONTROL = 0x08

WS_STATE_OFF, WS_STATE_ON, WS_STATE_ERROR, WS_STATE_NOT_INSTALLED = 0, 1, 2, 3

ACTIVATION_OK = 0x00
ACTIVATION_DDOP_ERRORS = 0x01
ACTIVATION_OTHER_ERROR = 0x04

PGN_LANGUAGE_COMMAND = 0xFE0F
# "en", decimal point, 24 h, ddmmyyyy, metric units throughout, reserved
LANGUAGE_COMMAND = b"en\x4f\x00\x00\x00\xff\xff"
LOCALIZATION_LABEL = LANGUAGE_COMMAND[:7]


def version_message(options: int, booms: int, sections: int, channels: int = 0) -> bytes:
    """Technical capabilities version response (0x10), TC version ``TC_VERSION``, boot time
    not available."""
    return bytes(
        (0x10, TC_VERSION, 0xFF, options & 0xFF, 0x00, booms & 0xFF, sections & 0xFF, channels)
    )


@dataclass(frozen=True)
class PD:
    command: int
    element: int
    ddi: int
    value: int

    def to_bytes(self) -> bytes:
        return encode(self.command, self.element, self.ddi, self.value)


def encode(command: int, element: int, ddi: int, value: int) -> bytes:
    """An 8-byte process data message; the value is sent as a 32-bit integer (bit fields
    such as a condensed work state above 2**31 are sent as their bit pattern)."""
    value = int(value)
    if 2**31 <= value < 2**32:
        value -= 2**32
    value = max(-(2**31), min(2**31 - 1, value))
    b0 = (command & 0x0F) | ((element & 0x0F) << 4)
    return bytes((b0, (element >> 4) & 0xFF)) + struct.pack("<Hi", ddi & 0xFFFF, value)


def decode(data: bytes) -> PD:
    """Parse an 8-byte process data message (ValueError when shorter)."""
    if len(data) < 8:
        raise ValueError(f"process data message of {len(data)} bytes (needs 8)")
    element = (data[0] >> 4) | (data[1] << 4)
    ddi, value = struct.unpack("<Hi", data[2:8])
    return PD(data[0] & 0x0F, element, ddi, value)


def condensed_work_state(states: list[bool], n_slots: int = 16) -> int:
    """Sections 1..16 in two bits each, section 1 in the least significant bits: 01 on,
    00 off, 11 not installed (slots without a section)."""
    v = 0
    for k in range(n_slots):
        s = (
            (WS_STATE_ON if states[k] else WS_STATE_OFF)
            if k < len(states)
            else WS_STATE_NOT_INSTALLED
        )
        v |= s << (2 * k)
    return v


def sections_on(value: int, n: int) -> list[bool]:
    return [((value >> (2 * k)) & 0x3) == WS_STATE_ON for k in range(n)]


def mss_payload(speed_m_s: float, distance_m: float, source: int = 2) -> bytes:
    """Machine selected speed (PGN 0xF022): source 2 = navigation-based (GNSS), forward."""
    sp = max(0, min(0xFAFF, int(round(speed_m_s * 1000))))
    dist = int(round(distance_m * 1000)) % 0xFAFFFFFF
    b7 = 0x01 | ((source & 0x7) << 2)  # direction forward, limit status 0 (not limited)
    return struct.pack("<HI", sp, dist) + bytes((0xFF, b7))


def mss_speed(data: bytes) -> float | None:
    """Speed in m/s from a machine selected speed message; None when not available."""
    if len(data) < 8:
        return None
    sp = data[0] | data[1] << 8
    if sp > 0xFAFF:
        return None
    return sp / 1000.0
