"""CAN transport: any python-can interface chosen by one ``--can`` option.

    socketcan:can0                    Linux SocketCAN (PEAK/Kvaser/... behind the kernel driver)
    pcan:PCAN_USBBUS1                 PEAK PCAN-Basic
    slcan:/dev/ttyACM0@500000         LAWICEL/slcan serial adapters (the @ is the serial baud
                                      rate, python-can's slcan channel syntax)
    socketcand:HOST:PORT:CHANNEL      a socketcand daemon on the network
    virtual:NAME                      python-can's in-process bus (tests, simulation)
    IFACE:CHANNEL                     any other python-can interface name

ISOBUS runs at 250 kbit/s (ISO 11783-2); that is the default bit rate. Interfaces that
configure the bit rate themselves (socketcan: ``ip link set can0 type can bitrate 250000``,
socketcand, virtual) ignore it.
"""

from __future__ import annotations

from typing import Any

ISOBUS_BITRATE = 250_000

INTERFACES = ("socketcan", "pcan", "slcan", "socketcand", "virtual", "kvaser", "vector", "gs_usb")


class CanSpecError(ValueError):
    """A ``--can`` value that names no interface or channel."""


def parse_can_spec(spec: str, bitrate: int = ISOBUS_BITRATE) -> dict[str, Any]:
    """``--can`` value -> keyword arguments for ``can.Bus``."""
    iface, sep, rest = spec.partition(":")
    iface = iface.strip().lower()
    if not sep or not iface or not rest:
        raise CanSpecError(f"--can {spec!r}: expected INTERFACE:CHANNEL, e.g. socketcan:can0")
    if iface == "socketcand":
        parts = rest.split(":")
        if len(parts) != 3 or not parts[1].isdigit():
            raise CanSpecError(f"--can {spec!r}: expected socketcand:HOST:PORT:CHANNEL")
        # tcp_tune: TCP_NODELAY (and QUICKACK) on the daemon's socket. Without it Nagle's
        # algorithm holds a frame written right after another (the set point after the
        # machine selected speed) until the first is acknowledged: tens of ms per set point.
        return {
            "interface": "socketcand",
            "host": parts[0],
            "port": int(parts[1]),
            "channel": parts[2],
            "tcp_tune": True,
        }
    if iface == "virtual":
        return {"interface": "virtual", "channel": rest, "receive_own_messages": False}
    if iface == "socketcan":
        return {"interface": "socketcan", "channel": rest}
    return {"interface": iface, "channel": rest, "bitrate": int(bitrate)}


def open_bus(spec: str, bitrate: int = ISOBUS_BITRATE) -> Any:
    """Open the python-can bus named by ``spec`` (python-can imported lazily)."""
    import can

    return can.Bus(**parse_can_spec(spec, bitrate))
