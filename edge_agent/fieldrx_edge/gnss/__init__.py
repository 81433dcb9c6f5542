"""GNSS input: NMEA sources, parsing into fixes, and the UTM projection."""

from fieldrx_edge.gnss.parser import Fix, NmeaParser, ParseStats
from fieldrx_edge.gnss.sources import file_lines, open_source, serial_lines, tcp_lines, udp_lines
from fieldrx_edge.gnss.utm import UtmProjection

__all__ = [
    "Fix",
    "NmeaParser",
    "ParseStats",
    "UtmProjection",
    "file_lines",
    "open_source",
    "serial_lines",
    "tcp_lines",
    "udp_lines",
]
