"""Uploaded archives and XML read defensively: bounded, streaming, no traversal, no DTDs.

``read_zip`` inflates members in chunks and counts what actually comes out
(the sizes a zip header declares are not trusted): each member and the sum
are capped, so a zip bomb stops at the cap, not at the memory limit. Member
names that are absolute, contain ``..``, a drive letter, or are symlinks are
refused: the archive is never extracted to disk, but a name like
``../TASKDATA.XML`` is still a sign of a hostile archive and is named in
the error.

``parse_xml`` parses with expat and refuses any document type declaration:
without a DTD there are no entity declarations, so neither entity expansion
("billion laughs") nor external entities can happen (the rule defusedxml's
``forbid_dtd=True`` applies; defusedxml is not a dependency of FieldRx).
"""

from __future__ import annotations

import io
import os
import stat
import xml.etree.ElementTree as ET
import zipfile
import zlib
from pyexpat import ExpatError, ParserCreate
from typing import Any, NoReturn

from fieldrx.formats import FormatError

MAX_MEMBERS = 5_000
MAX_MEMBER_BYTES = 256 * 1024 * 1024
MAX_TOTAL_BYTES = 512 * 1024 * 1024
CHUNK = 1 << 20


def safe_member_name(name: str) -> str:
    """The member's path with '/' separators, or ``FormatError`` if it could escape a folder."""
    n = name.replace("\\", "/")
    parts = [p for p in n.split("/") if p not in ("", ".")]
    if n.startswith("/") or ".." in parts or (parts and len(parts[0]) == 2 and parts[0][1] == ":"):
        raise FormatError(f"{name}: archive member path leaves the archive (path traversal)")
    return "/".join(parts)


def read_zip(
    data: bytes | str | os.PathLike[str],
    *,
    max_member_bytes: int = MAX_MEMBER_BYTES,
    max_total_bytes: int = MAX_TOTAL_BYTES,
    max_members: int = MAX_MEMBERS,
) -> dict[str, bytes]:
    """Every file of a zip (its bytes, or a path: an upload spooled to disk), inflated
    under the limits (see module docstring)."""
    try:
        z = zipfile.ZipFile(io.BytesIO(data) if isinstance(data, bytes) else data)
    except zipfile.BadZipFile as exc:
        raise FormatError("not a zip file") from exc
    infos = z.infolist()
    if len(infos) > max_members:
        raise FormatError(f"the zip holds {len(infos)} members (> {max_members})")
    out: dict[str, bytes] = {}
    total = 0
    for info in infos:
        name = safe_member_name(info.filename)
        if info.is_dir() or not name or name.startswith("__MACOSX/"):
            continue
        if stat.S_ISLNK(info.external_attr >> 16):
            raise FormatError(f"{info.filename}: symbolic links are not accepted in archives")
        if info.file_size > max_member_bytes:
            raise FormatError(
                f"{info.filename}: declares {info.file_size} bytes uncompressed "
                f"(> {max_member_bytes} per file)"
            )
        buf = bytearray()
        try:
            with z.open(info) as f:
                while chunk := f.read(CHUNK):
                    buf += chunk
                    total += len(chunk)
                    if len(buf) > max_member_bytes:
                        raise FormatError(
                            f"{info.filename}: inflates to more than {max_member_bytes} bytes"
                        )
                    if total > max_total_bytes:
                        raise FormatError(
                            f"the archive inflates to more than {max_total_bytes} bytes "
                            f"(stopped in {info.filename})"
                        )
        except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
            raise FormatError(f"{info.filename}: cannot be inflated ({exc})") from exc
        out[name] = bytes(buf)
    return out


def parse_xml(data: bytes, where: str) -> ET.Element:
    """An ElementTree of ``data``; any DOCTYPE, malformed XML: ``FormatError`` naming ``where``."""
    builder = ET.TreeBuilder()
    p = ParserCreate()

    def no_dtd(*_: Any) -> NoReturn:
        raise FormatError(
            f"{where}: XML document type declarations (DTD/entities) are not accepted"
        )

    p.StartDoctypeDeclHandler = no_dtd
    p.EntityDeclHandler = no_dtd
    p.ExternalEntityRefHandler = no_dtd
    p.StartElementHandler = lambda tag, attrs: builder.start(tag, attrs)
    p.EndElementHandler = lambda tag: builder.end(tag)
    p.CharacterDataHandler = builder.data
    p.buffer_text = True
    p.ordered_attributes = False
    try:
        p.Parse(data, True)
    except ExpatError as exc:
        raise FormatError(f"{where}: malformed XML ({exc})") from exc
    try:
        return builder.close()
    except AssertionError as exc:  # empty document
        raise FormatError(f"{where}: no XML element") from exc
