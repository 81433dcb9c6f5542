"""ISO 11783-10 device descriptor object pool (DDOP), binary transfer format.

Every object starts with its three-letter table id and its 16-bit object id; all integers
are little-endian, strings are length-prefixed (1 byte) UTF-8 (ISO 11783-10:2015 Annex A,
object definitions; Annex B.1 binary format):

    DVC  id | designator | software version | working-set NAME (8) | serial number |
         structure label (7) | localization label (7) |
         [version >= 4: extended structure label length (1, always present, 0 when
          there is none) + up to 32 bytes]
    DET  id | element type (1) | designator | element number (2) | parent object id (2) |
         number of objects to follow (2) | object ids (2 each) of its DPD / DPT objects
    DPD  id | DDI (2) | properties (1) | trigger methods (1) | designator | DVP object id (2)
    DPT  id | DDI (2) | value (int32) | designator | DVP object id (2)
    DVP  id | offset (int32) | scale (float32) | number of decimals (1) | unit designator

Pool rules checked (Annex A: A.2 DVC, A.3 DET, A.4 DPD, A.5 DPT, A.6 DVP): one DVC, and it
is object 0; exactly one device element (type 1), whose parent is the DVC; every other
element's parent is an element, and the parents lead to the device element without a
cycle (the element tree is given by the parent ids, never by child lists); an element's
"objects to follow" are its own DPD and DPT objects only; element numbers unique and at
most 4095 (12 bits in a process data message); object ids unique and not 0xFFFF ("no
object"); every DVP reference resolves to a DVP; designators at most 32 bytes before
version 4 and 128 bytes from version 4 on; reserved property / trigger bits clear.

Element types: 1 device, 2 function, 3 bin, 4 section, 5 unit, 6 connector, 7 navigation.
DPD properties: bit 0 member of default set, bit 1 settable, bit 2 control source.
DPD trigger methods: bit 0 time interval, bit 1 distance interval, bit 2 threshold limits,
bit 3 on change, bit 4 total. A DVP only presents a value (displayed = (raw + offset) *
scale with the given decimals and unit); the value on the bus stays in the DDI's
resolution. Object id 0xFFFF means "no object".

Public descriptions used: AgIsoStack++ ``isobus_task_controller_client_objects.cpp``
(``get_binary_object`` of DeviceObject with its version-4 extended structure label byte,
DeviceElementObject, DeviceProcessDataObject, DevicePropertyObject,
DeviceValuePresentationObject) and ``isobus_device_descriptor_object_pool.cpp``
(designator limits per version, child references of elements), its task controller
client example pool (device object 0, device element parent 0, element children = its
DPD/DPT objects), and the isoxml package's DDI table (isoxml.models.ddi_entities, from
isobus.net's data dictionary) for DDI units.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass, field

from fieldrx_edge.isobus.j1939 import Name

NULL_ID = 0xFFFF
DEVICE_OBJECT_ID = 0  # the DVC's object id (ISO 11783-10 Annex A.2)

ELEMENT_DEVICE = 1
ELEMENT_FUNCTION = 2
ELEMENT_BIN = 3
ELEMENT_SECTION = 4
ELEMENT_NAVIGATION = 7
MAX_ELEMENT_NUMBER = 4095

PROP_DEFAULT_SET = 0x01
PROP_SETTABLE = 0x02
PROP_CONTROL_SOURCE = 0x04

TRIG_TIME = 0x01
TRIG_DISTANCE = 0x02
TRIG_THRESHOLD = 0x04
TRIG_CHANGE = 0x08
TRIG_TOTAL = 0x10

DDOP_VERSION = 4  # the TC / client version whose layout FieldRx writes
MAX_EXT_LABEL = 32

# activation response byte 6, "object pool error codes" (ISO 11783-10 B.5.17, AgIsoStack++
# ObjectPoolErrorCodes)
POOL_ERR_NOT_SUPPORTED = 0x01
POOL_ERR_UNKNOWN_REFERENCE = 0x02
POOL_ERR_OTHER = 0x04


def max_designator(version: int) -> int:
    """Designator bytes allowed: 32 up to version 3, 128 (UTF-8) from version 4."""
    return 128 if version >= 4 else 32


class DdopError(ValueError):
    """A device descriptor that cannot be parsed or used; ``object_id`` names the culprit,
    ``parent_id`` its parent, ``code`` the object-pool error code for the activation
    response."""

    def __init__(
        self,
        msg: str,
        object_id: int = NULL_ID,
        parent_id: int = NULL_ID,
        code: int = POOL_ERR_OTHER,
    ) -> None:
        super().__init__(msg)
        self.object_id = object_id
        self.parent_id = parent_id
        self.code = code


@dataclass
class Device:
    object_id: int
    designator: str
    software_version: str
    name: Name
    serial_number: str
    structure_label: bytes = b"FRX0001"
    localization_label: bytes = b"en\x00\x00\x00\x00\xff"
    extended_structure_label: bytes | None = None


@dataclass
class Element:
    object_id: int
    element_type: int
    designator: str
    element_number: int
    parent_id: int
    children: list[int] = field(default_factory=list)


@dataclass
class ProcessData:
    object_id: int
    ddi: int
    properties: int
    triggers: int
    designator: str
    presentation_id: int = NULL_ID


@dataclass
class Property:
    object_id: int
    ddi: int
    value: int
    designator: str
    presentation_id: int = NULL_ID


@dataclass
class Presentation:
    object_id: int
    offset: int
    scale: float
    decimals: int
    unit: str

    def show(self, raw: int) -> str:
        return f"{(raw + self.offset) * self.scale:.{self.decimals}f} {self.unit}".strip()


Obj = Device | Element | ProcessData | Property | Presentation


def _s(text: str | bytes, limit: int = 255) -> bytes:
    b = text.encode("utf-8") if isinstance(text, str) else text
    if len(b) > limit:
        raise DdopError(f"designator longer than {limit} bytes: {b[:20]!r}...")
    return bytes((len(b),)) + b


def _label(b: bytes) -> bytes:
    return (bytes(b) + b" " * 7)[:7]


def encode_object(o: Obj, version: int = DDOP_VERSION) -> bytes:
    """One object in the binary layout of TC ``version`` (module docstring)."""
    lim = max_designator(version)
    if isinstance(o, Device):
        out = b"DVC" + struct.pack("<H", o.object_id) + _s(o.designator, lim)
        out += _s(o.software_version, lim) + o.name.to_bytes() + _s(o.serial_number, lim)
        out += _label(o.structure_label) + _label(o.localization_label)
        if version >= 4:  # A.2: the length byte is always there from version 4 on
            out += _s(o.extended_structure_label or b"", MAX_EXT_LABEL)
        elif o.extended_structure_label:
            raise DdopError("an extended structure label needs TC version 4", o.object_id)
        return out
    if isinstance(o, Element):
        out = b"DET" + struct.pack("<HB", o.object_id, o.element_type) + _s(o.designator, lim)
        out += struct.pack("<HHH", o.element_number, o.parent_id, len(o.children))
        return out + b"".join(struct.pack("<H", c) for c in o.children)
    if isinstance(o, ProcessData):
        out = b"DPD" + struct.pack("<HHBB", o.object_id, o.ddi, o.properties, o.triggers)
        return out + _s(o.designator, lim) + struct.pack("<H", o.presentation_id)
    if isinstance(o, Property):
        out = b"DPT" + struct.pack("<HHi", o.object_id, o.ddi, o.value)
        return out + _s(o.designator, lim) + struct.pack("<H", o.presentation_id)
    if isinstance(o, Presentation):
        out = b"DVP" + struct.pack("<Hif", o.object_id, o.offset, o.scale)
        return out + bytes((o.decimals & 0xFF,)) + _s(o.unit, lim)
    raise TypeError(f"not a DDOP object: {o!r}")


class _Reader:
    def __init__(self, data: bytes, version: int) -> None:
        self.d = data
        self.i = 0
        self.obj = NULL_ID
        self.limit = max_designator(version)

    def take(self, n: int) -> bytes:
        if self.i + n > len(self.d):
            raise DdopError(
                f"DDOP truncated at byte {self.i} (object {self.obj}): needs {n} more", self.obj
            )
        b = self.d[self.i : self.i + n]
        self.i += n
        return b

    def u8(self) -> int:
        return self.take(1)[0]

    def u16(self) -> int:
        return struct.unpack("<H", self.take(2))[0]

    def i32(self) -> int:
        return struct.unpack("<i", self.take(4))[0]

    def f32(self) -> float:
        return struct.unpack("<f", self.take(4))[0]

    def text(self, what: str = "designator", limit: int | None = None) -> str:
        at = self.i
        n = self.u8()
        lim = self.limit if limit is None else limit
        if n > lim:
            raise DdopError(
                f"object {self.obj}: {what} of {n} bytes at byte {at} (at most {lim})", self.obj
            )
        raw = self.take(n)
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            return raw.decode("latin-1")  # ISO 8859-1 designators of version 3 pools


def _read_object(r: _Reader, tag: bytes, oid: int, version: int) -> Obj:
    if tag == b"DVC":
        desig, sw = r.text(), r.text("software version")
        name = Name.from_bytes(r.take(8))
        serial = r.text("serial number")
        sl, ll = r.take(7), r.take(7)
        ext = None
        if version >= 4:  # always present at version 4 (0 = no extended label)
            n = r.u8()
            if n > MAX_EXT_LABEL:
                raise DdopError(
                    f"DVC {oid}: extended structure label of {n} bytes (at most 32)", oid
                )
            ext = r.take(n) if n else None
        return Device(oid, desig, sw, name, serial, sl, ll, ext)
    if tag == b"DET":
        et = r.u8()
        desig = r.text()
        num, parent, n = r.u16(), r.u16(), r.u16()
        return Element(oid, et, desig, num, parent, [r.u16() for _ in range(n)])
    if tag == b"DPD":
        ddi, props, trig = r.u16(), r.u8(), r.u8()
        return ProcessData(oid, ddi, props, trig, r.text(), r.u16())
    if tag == b"DPT":
        ddi, val = r.u16(), r.i32()
        return Property(oid, ddi, val, r.text(), r.u16())
    if tag == b"DVP":
        off, scale, dec = r.i32(), r.f32(), r.u8()
        return Presentation(oid, off, scale, dec, r.text("unit designator"))
    raise DdopError(f"unknown object type {tag!r} at byte {r.i - 5}", oid)


def parse(data: bytes, version: int = DDOP_VERSION) -> DeviceDescriptor:
    """Parse a binary DDOP in the layout of the client's TC ``version`` and check the pool
    rules (module docstring). Raises ``DdopError`` naming the object on any violation."""
    r = _Reader(bytes(data), version)
    objs: list[Obj] = []
    while r.i < len(r.d):
        tag = r.take(3)
        r.obj = NULL_ID
        oid = r.u16()
        r.obj = oid
        objs.append(_read_object(r, tag, oid, version))
    return DeviceDescriptor(objs, version)


@dataclass
class Binding:
    """Where a DDI lives: the element number to address and its process data object."""

    element_number: int
    element_id: int
    ddi: int
    pd: ProcessData | Property
    presentation: Presentation | None


class DeviceDescriptor:
    """A pool with the ISO 11783-10 pool rules checked (module docstring); raises
    ``DdopError`` naming the faulty object and its parent."""

    def __init__(self, objects: list[Obj], version: int = DDOP_VERSION) -> None:
        self.objects = objects
        self.version = version
        self.by_id: dict[int, Obj] = {}
        for o in objects:
            if o.object_id in self.by_id or o.object_id == NULL_ID:
                raise DdopError(f"object id {o.object_id} used twice or reserved", o.object_id)
            self.by_id[o.object_id] = o
        devs = [o for o in objects if isinstance(o, Device)]
        if len(devs) != 1:
            raise DdopError(f"a DDOP needs exactly one DVC object, found {len(devs)}")
        self.device = devs[0]
        if self.device.object_id != DEVICE_OBJECT_ID:
            raise DdopError(
                f"the DVC object has id {self.device.object_id}; the device object is object 0",
                self.device.object_id,
            )
        self.elements = [o for o in objects if isinstance(o, Element)]
        self._check_elements()
        self._check_children()
        for o in objects:
            pid = getattr(o, "presentation_id", NULL_ID)
            if pid != NULL_ID and not isinstance(self.by_id.get(pid), Presentation):
                raise DdopError(
                    f"object {o.object_id} references missing DVP {pid}",
                    pid,
                    o.object_id,
                    POOL_ERR_UNKNOWN_REFERENCE,
                )
            if isinstance(o, ProcessData) and (o.properties & ~0x07 or o.triggers & ~0x1F):
                raise DdopError(
                    f"DPD {o.object_id}: reserved property/trigger bits set "
                    f"(0x{o.properties:02X} / 0x{o.triggers:02X})",
                    o.object_id,
                    code=POOL_ERR_NOT_SUPPORTED,
                )

    def _check_elements(self) -> None:
        devices = [e for e in self.elements if e.element_type == ELEMENT_DEVICE]
        if len(devices) != 1:
            raise DdopError(f"a DDOP needs exactly one device element, found {len(devices)}")
        numbers: set[int] = set()
        for e in self.elements:
            if not 1 <= e.element_type <= ELEMENT_NAVIGATION:
                raise DdopError(f"element {e.object_id} has type {e.element_type}", e.object_id)
            if e.element_number > MAX_ELEMENT_NUMBER or e.element_number in numbers:
                raise DdopError(
                    f"element {e.object_id}: element number {e.element_number} repeated or "
                    f"above {MAX_ELEMENT_NUMBER}",
                    e.object_id,
                    e.parent_id,
                )
            numbers.add(e.element_number)
            if e.element_type == ELEMENT_DEVICE:
                if e.parent_id != self.device.object_id:
                    raise DdopError(
                        f"device element {e.object_id} has parent {e.parent_id}; "
                        f"its parent is the DVC ({self.device.object_id})",
                        e.object_id,
                        e.parent_id,
                    )
                continue
            seen = {e.object_id}
            par = self.by_id.get(e.parent_id)
            while isinstance(par, Element) and par.element_type != ELEMENT_DEVICE:
                if par.object_id in seen:
                    raise DdopError(f"element {e.object_id}: parent cycle", e.object_id)
                seen.add(par.object_id)
                par = self.by_id.get(par.parent_id)
            if not isinstance(par, Element):
                raise DdopError(
                    f"element {e.object_id} has no parent element {e.parent_id} leading to "
                    "the device element",
                    e.object_id,
                    e.parent_id,
                    POOL_ERR_UNKNOWN_REFERENCE,
                )

    def _check_children(self) -> None:
        for e in self.elements:
            for c in e.children:
                ch = self.by_id.get(c)
                if ch is None:
                    raise DdopError(
                        f"element {e.object_id} references missing child {c}",
                        c,
                        e.object_id,
                        POOL_ERR_UNKNOWN_REFERENCE,
                    )
                if not isinstance(ch, ProcessData | Property):
                    raise DdopError(
                        f"element {e.object_id} lists object {c} ({type(ch).__name__}) among "
                        "its objects; an element's objects are its DPD/DPT only (the tree "
                        "is given by parent ids)",
                        c,
                        e.object_id,
                    )

    def to_bytes(self, version: int | None = None) -> bytes:
        v = self.version if version is None else version
        return b"".join(encode_object(o, v) for o in self.objects)

    def find(self, ddi: int, settable: bool | None = None) -> list[Binding]:
        """Every element that carries ``ddi`` (as process data or property)."""
        out = []
        for e in self.elements:
            for c in e.children:
                pd = self.by_id.get(c)
                if isinstance(pd, ProcessData | Property) and pd.ddi == ddi:
                    if settable is not None and isinstance(pd, ProcessData):
                        if bool(pd.properties & PROP_SETTABLE) != settable:
                            continue
                    if settable and isinstance(pd, Property):
                        continue  # a property is a constant, never settable
                    pres = self.by_id.get(pd.presentation_id)
                    out.append(
                        Binding(
                            e.element_number,
                            e.object_id,
                            ddi,
                            pd,
                            pres if isinstance(pres, Presentation) else None,
                        )
                    )
        return out

    def sections(self) -> list[Element]:
        return [e for e in self.elements if e.element_type == ELEMENT_SECTION]


# -- the rate ECU's own DDOP ----------------------------------------------------


def rate_ecu_ddop(
    name: Name,
    width_m: float,
    sections: int = 1,
    serial: str = "0001",
    structure_label: bytes | None = None,
) -> DeviceDescriptor:
    """FieldRx's metering ECU described for any TC: a device, one metering function with
    setpoint/actual mass per area (DDI 6/7), actual shaft speed (DDI 390), setpoint/actual
    condensed work state (DDI 290/161), working width (DDI 67) and ``sections`` section
    elements with their widths and offsets (DDI 67, 134 X, 135 Y). Many sections make a
    large pool (about 90 bytes each), like real boom implements.

    The structure label must change whenever the pool does (a TC that already holds a
    pool with the client's NAME and label reuses it without an upload), so by default it
    is derived from the pool's own bytes: "FX" + 5 hex digits of their SHA-1."""
    from fieldrx_edge.isobus import process_data as pdm

    dvc = Device(
        DEVICE_OBJECT_ID,
        "FieldRx rate ECU",
        "fieldrx-edge 0.1",
        name,
        serial,
        b"FX00000",
        pdm.LOCALIZATION_LABEL,
    )
    objs: list[Obj] = [dvc]
    nid = [100]

    def new_id() -> int:
        nid[0] += 1
        return nid[0]

    dvp_rate = Presentation(new_id(), 0, 0.01, 1, "kg/ha")
    dvp_mm = Presentation(new_id(), 0, 0.001, 2, "m")
    dvp_rpm = Presentation(new_id(), 0, 0.0001, 1, "r/min")
    objs += [dvp_rate, dvp_mm, dvp_rpm]
    # the element tree by parent ids: device element under the DVC, metering under it
    dev = Element(1, ELEMENT_DEVICE, "FieldRx spreader", 0, DEVICE_OBJECT_ID)
    meter = Element(2, ELEMENT_FUNCTION, "Metering", 1, dev.object_id)
    objs += [dev, meter]
    width_mm = int(round(width_m * 1000))
    for ddi, props, trig, label, pres in (
        (
            pdm.DDI_SETPOINT_MASS_PER_AREA,
            PROP_SETTABLE | PROP_DEFAULT_SET,
            TRIG_CHANGE,
            "Setpoint rate",
            dvp_rate,
        ),
        (
            pdm.DDI_ACTUAL_MASS_PER_AREA,
            PROP_DEFAULT_SET,
            TRIG_TIME | TRIG_DISTANCE | TRIG_CHANGE,
            "Actual rate",
            dvp_rate,
        ),
        (pdm.DDI_ACTUAL_REVOLUTIONS, 0, TRIG_TIME | TRIG_CHANGE, "Shaft speed", dvp_rpm),
        (
            pdm.DDI_SETPOINT_CONDENSED_WORK_STATE,
            PROP_SETTABLE,
            TRIG_CHANGE,
            "Section setpoint",
            None,
        ),
        (
            pdm.DDI_ACTUAL_CONDENSED_WORK_STATE,
            PROP_DEFAULT_SET,
            TRIG_TIME | TRIG_CHANGE,
            "Section state",
            None,
        ),
    ):
        o = ProcessData(new_id(), ddi, props, trig, label, pres.object_id if pres else NULL_ID)
        objs.append(o)
        meter.children.append(o.object_id)
    w = Property(new_id(), pdm.DDI_ACTUAL_WORKING_WIDTH, width_mm, "Width", dvp_mm.object_id)
    objs.append(w)
    meter.children.append(w.object_id)
    sw = width_mm // max(1, sections)
    for k in range(sections):
        sec = Element(new_id(), ELEMENT_SECTION, f"Section {k + 1}", 2 + k, meter.object_id)
        objs.append(sec)
        y = int(-width_mm / 2 + sw * (k + 0.5))
        for ddi, val, label in (
            (pdm.DDI_ACTUAL_WORKING_WIDTH, sw, "Section width"),
            (pdm.DDI_OFFSET_X, 0, "Offset X"),
            (pdm.DDI_OFFSET_Y, y, "Offset Y"),
        ):
            p = Property(new_id(), ddi, val, label, dvp_mm.object_id)
            objs.append(p)
            sec.children.append(p.object_id)
    if structure_label is None:
        digest = hashlib.sha1(b"".join(encode_object(o) for o in objs)).hexdigest()
        structure_label = b"FX" + digest[:5].upper().encode("ascii")
    dvc.structure_label = structure_label
    return DeviceDescriptor(objs)
