"""NMEA-0183 sentence writer: the simulator speaks what a receiver would."""

from __future__ import annotations

import time


def checksum(body: str) -> str:
    c = 0
    for ch in body:
        c ^= ord(ch)
    return f"{c:02X}"


def sentence(body: str) -> str:
    return f"${body}*{checksum(body)}"


def _lat(lat: float) -> tuple[str, str]:
    a = abs(lat)
    d = int(a)
    return f"{d:02d}{(a - d) * 60:010.7f}", "N" if lat >= 0 else "S"


def _lon(lon: float) -> tuple[str, str]:
    a = abs(lon)
    d = int(a)
    return f"{d:03d}{(a - d) * 60:010.7f}", "E" if lon >= 0 else "W"


def _hms(t: float) -> tuple[str, str]:
    cs = int(round(t * 100))
    st = time.gmtime(cs // 100)
    return (
        f"{st.tm_hour:02d}{st.tm_min:02d}{st.tm_sec:02d}.{cs % 100:02d}",
        f"{st.tm_mday:02d}{st.tm_mon:02d}{st.tm_year % 100:02d}",
    )


def rmc(
    t: float,
    lat: float,
    lon: float,
    speed_m_s: float,
    course_deg: float,
    valid: bool = True,
    talker: str = "GN",
) -> str:
    hms, dmy = _hms(t)
    la, ns = _lat(lat)
    lo, ew = _lon(lon)
    kn = speed_m_s / (1852.0 / 3600.0)
    status = "A" if valid else "V"
    mode = "R" if valid else "N"
    cog = f"{course_deg % 360:.2f}"
    return sentence(f"{talker}RMC,{hms},{status},{la},{ns},{lo},{ew},{kn:.3f},{cog},{dmy},,,{mode}")


def gga(
    t: float,
    lat: float,
    lon: float,
    quality: int = 4,
    sats: int = 14,
    hdop: float = 0.7,
    alt: float = 100.0,
    talker: str = "GN",
) -> str:
    hms, _ = _hms(t)
    la, ns = _lat(lat)
    lo, ew = _lon(lon)
    return sentence(
        f"{talker}GGA,{hms},{la},{ns},{lo},{ew},{quality},{sats:02d},{hdop:.1f},{alt:.1f},M,40.0,M,,"
    )


def vtg(speed_m_s: float, course_deg: float, talker: str = "GN") -> str:
    kn = speed_m_s / (1852.0 / 3600.0)
    return sentence(f"{talker}VTG,{course_deg % 360:.2f},T,,M,{kn:.3f},N,{speed_m_s * 3.6:.3f},K,A")
