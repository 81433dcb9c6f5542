"""ISO 11783-3 / SAE J1939-21 identifiers and ISO 11783-5 / J1939-81 NAMEs.

29-bit CAN identifier (ISO 11783-3 sec. 5.2, J1939-21 sec. 5.1.2), most significant bit first:

    priority (3) | EDP (1) | data page (1) | PF (8) | PS (8) | source address SA (8)

PF < 240 (PDU1): PS is the destination address and the PGN's low byte is 0. PF >= 240
(PDU2): broadcast only, PS is part of the PGN (group extension).

NAME (ISO 11783-5 sec. 4.3.1, J1939-81 sec. 4.1.1), 64 bits sent least significant byte
first in the address-claimed message (PGN 0xEE00):

    bit 63 self-configurable address | 62-60 industry group | 59-56 device class instance |
    55-49 device class | 48 reserved | 47-40 function | 39-35 function instance |
    34-32 ECU instance | 31-21 manufacturer code | 20-0 identity number

A numerically lower NAME has the higher priority in address contention.

Public descriptions used: AgIsoStack++ ``can_identifier.cpp`` / ``can_NAME.cpp`` and its
"ISOBUS concepts" page (https://github.com/Open-Agriculture/AgIsoStack-plus-plus,
sphinx/source/Concepts.rst); the isobus.net PGN list (https://www.isobus.net/isobus/pGNAndSPN).
"""

from __future__ import annotations

from dataclasses import dataclass

GLOBAL_ADDRESS = 0xFF
NULL_ADDRESS = 0xFE  # "cannot claim" source address

# PGNs (ISO 11783-3 / -5 / -7 / -10 as listed by isobus.net and AgIsoStack++
# can_general_parameter_group_numbers.hpp)
PGN_REQUEST = 0xEA00  # request (3-byte PGN payload)
PGN_ADDRESS_CLAIM = 0xEE00  # address claimed / cannot claim
PGN_ACKNOWLEDGE = 0xE800
PGN_TP_CM = 0xEC00  # transport protocol connection management
PGN_TP_DT = 0xEB00  # transport protocol data transfer
PGN_ETP_CM = 0xC800  # extended transport protocol connection management
PGN_ETP_DT = 0xC700  # extended transport protocol data transfer
PGN_PROCESS_DATA = 0xCB00  # ISO 11783-10 process data
PGN_WORKING_SET_MASTER = 0xFE0D  # ISO 11783-7 working set master
PGN_MACHINE_SELECTED_SPEED = 0xF022  # ISO 11783-7 machine selected speed

# NAME function codes (ISO 11783-1 Annex / isobus.net "NAME functions")
FUNCTION_TASK_CONTROLLER = 130
FUNCTION_RATE_CONTROL = 128  # "machine control" (non-specific implement ECU)
INDUSTRY_GROUP_AGRICULTURE = 2


def pgn3(pgn: int) -> bytes:
    """A PGN as the 3 little-endian bytes requests, acknowledgements and transport
    protocol messages carry."""
    return bytes((pgn & 0xFF, (pgn >> 8) & 0xFF, (pgn >> 16) & 0xFF))


def u24(b: bytes) -> int:
    """The 3-byte little-endian number at the start of ``b`` (a PGN, a packet offset)."""
    return b[0] | b[1] << 8 | b[2] << 16


def encode_id(pgn: int, sa: int, da: int = GLOBAL_ADDRESS, priority: int = 6) -> int:
    """29-bit identifier for a PGN from ``sa`` to ``da`` (da ignored for PDU2 PGNs)."""
    pf = (pgn >> 8) & 0xFF
    dp = (pgn >> 16) & 0x03
    ps = (da & 0xFF) if pf < 240 else (pgn & 0xFF)
    return ((priority & 0x7) << 26) | (dp << 24) | (pf << 16) | (ps << 8) | (sa & 0xFF)


def decode_id(can_id: int) -> tuple[int, int, int, int]:
    """(pgn, sa, da, priority) of a 29-bit identifier; da is 0xFF for PDU2 PGNs."""
    priority = (can_id >> 26) & 0x7
    dp = (can_id >> 24) & 0x03
    pf = (can_id >> 16) & 0xFF
    ps = (can_id >> 8) & 0xFF
    sa = can_id & 0xFF
    if pf < 240:
        return (dp << 16) | (pf << 8), sa, ps, priority
    return (dp << 16) | (pf << 8) | ps, sa, GLOBAL_ADDRESS, priority


@dataclass(frozen=True)
class Name:
    """An ISO 11783-5 NAME; ``value`` is the 64-bit integer (lower wins contention)."""

    identity_number: int = 0
    manufacturer_code: int = 0
    ecu_instance: int = 0
    function_instance: int = 0
    function: int = 0
    device_class: int = 0
    device_class_instance: int = 0
    industry_group: int = INDUSTRY_GROUP_AGRICULTURE
    self_configurable: bool = True

    @property
    def value(self) -> int:
        return (
            (self.identity_number & 0x1FFFFF)
            | (self.manufacturer_code & 0x7FF) << 21
            | (self.ecu_instance & 0x7) << 32
            | (self.function_instance & 0x1F) << 35
            | (self.function & 0xFF) << 40
            | (self.device_class & 0x7F) << 49
            | (self.device_class_instance & 0xF) << 56
            | (self.industry_group & 0x7) << 60
            | int(self.self_configurable) << 63
        )

    def to_bytes(self) -> bytes:
        return self.value.to_bytes(8, "little")

    @classmethod
    def from_value(cls, v: int) -> Name:
        return cls(
            identity_number=v & 0x1FFFFF,
            manufacturer_code=(v >> 21) & 0x7FF,
            ecu_instance=(v >> 32) & 0x7,
            function_instance=(v >> 35) & 0x1F,
            function=(v >> 40) & 0xFF,
            device_class=(v >> 49) & 0x7F,
            device_class_instance=(v >> 56) & 0xF,
            industry_group=(v >> 60) & 0x7,
            self_configurable=bool(v >> 63),
        )

    @classmethod
    def from_bytes(cls, b: bytes) -> Name:
        return cls.from_value(int.from_bytes(bytes(b[:8]), "little"))
