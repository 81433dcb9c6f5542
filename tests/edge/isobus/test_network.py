"""ISOBUS network management on python-can's virtual bus: address claim, TP, BAM, ETP."""

from __future__ import annotations

import itertools
import random

import can
import pytest
from fieldrx_edge.isobus.j1939 import (
    NULL_ADDRESS,
    PGN_ADDRESS_CLAIM,
    Name,
    decode_id,
    encode_id,
)
from fieldrx_edge.isobus.link import Message
from fieldrx_edge.isobus.network import Node, pump
from fieldrx_edge.isobus.transport import CanSpecError, parse_can_spec

_chan = itertools.count()
_open: list[Node] = []


@pytest.fixture(autouse=True)
def _close_nodes():
    yield
    while _open:
        _open.pop().close()


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def channel() -> str:
    return f"isobus-test-{next(_chan)}-{random.randrange(1 << 30)}"


def make(ch: str, clock: Clock, ident: int, addr: int, self_cfg: bool = True, **kw) -> Node:
    bus = can.Bus(interface="virtual", channel=ch, receive_own_messages=False)
    name = Name(
        identity_number=ident, manufacturer_code=1407, function=130, self_configurable=self_cfg
    )
    node = Node(bus, name, addr, clock=clock, label=f"n{ident}", **kw)
    _open.append(node)
    return node


def settle(nodes: list[Node], clock: Clock, seconds: float = 0.5, step: float = 0.01) -> None:
    for _ in range(int(seconds / step)):
        pump(nodes)
        clock.t += step
    pump(nodes)


def test_can_spec_covers_the_interfaces():
    assert parse_can_spec("socketcan:can0") == {"interface": "socketcan", "channel": "can0"}
    assert parse_can_spec("pcan:PCAN_USBBUS1")["bitrate"] == 250_000
    s = parse_can_spec("slcan:/dev/ttyACM0@500000")
    assert s["interface"] == "slcan" and s["channel"] == "/dev/ttyACM0@500000"
    s = parse_can_spec("socketcand:10.0.0.2:29536:can0")
    assert (s["host"], s["port"], s["channel"]) == ("10.0.0.2", 29536, "can0")
    assert parse_can_spec("virtual:x")["interface"] == "virtual"
    for bad in ("can0", "socketcand:host:can0", ":x", "virtual:"):
        with pytest.raises(CanSpecError):
            parse_can_spec(bad)


def test_identifier_round_trip_pdu1_and_pdu2():
    cid = encode_id(0xCB00, 0x80, 0xF7, 5)
    assert decode_id(cid) == (0xCB00, 0x80, 0xF7, 5)
    cid = encode_id(0xFE0D, 0x81, 0x33, 6)  # PDU2: destination ignored
    assert decode_id(cid) == (0xFE0D, 0x81, 0xFF, 6)
    n = Name(identity_number=12345, manufacturer_code=1407, function=130, device_class=4)
    assert Name.from_bytes(n.to_bytes()) == n


def test_address_claim_with_contention_lower_name_wins():
    clock, ch = Clock(), channel()
    a = make(ch, clock, ident=100, addr=0x80)  # higher NAME: loses
    b = make(ch, clock, ident=5, addr=0x80)
    a.start()
    b.start()
    settle([a, b], clock)
    assert b.address == 0x80 and b.claimed
    assert a.claimed and a.address not in (0x80, NULL_ADDRESS)
    assert a.stats.address_conflicts >= 1
    assert "isobus_address_lost" in a.alarms
    # two nodes that cannot pick another address: the higher NAME sends Cannot Claim
    # (the self-configurable bit is NAME bit 63, so these both outrank a and b)
    d = make(ch, clock, ident=3, addr=0x70, self_cfg=False)
    c = make(ch, clock, ident=999, addr=0x70, self_cfg=False)
    d.start()
    c.start()
    settle([a, b, c, d], clock)
    assert c.state == "failed" and c.address == NULL_ADDRESS
    assert d.address == 0x70 and b.address == 0x80


def test_reclaim_when_a_claimed_address_is_taken_by_a_higher_priority_name():
    clock, ch = Clock(), channel()
    a = make(ch, clock, ident=50, addr=0x90)
    a.start()
    settle([a], clock)
    assert a.address == 0x90
    moves: list[tuple[int, int]] = []
    a.on_address_change.append(lambda old, new: moves.append((old, new)))
    b = make(ch, clock, ident=1, addr=0x90)
    b.start()
    settle([a, b], clock)
    assert b.address == 0x90
    assert a.claimed and a.address != 0x90
    assert moves[0] == (0x90, NULL_ADDRESS) and moves[-1][1] == a.address


def test_request_for_address_claim_is_answered():
    clock, ch = Clock(), channel()
    a = make(ch, clock, ident=7, addr=0x85)
    a.start()
    settle([a], clock)
    b = make(ch, clock, ident=8, addr=0x86)  # joins later: never saw a's claim
    b.start()
    settle([b], clock)  # b never saw a's claim
    assert a.name not in b.peers.values()
    b.request(PGN_ADDRESS_CLAIM)
    settle([a, b], clock, 0.05)
    assert b.peers.get(0x85) == a.name


def _pair(**kw) -> tuple[Clock, Node, Node, list[Message]]:
    clock, ch = Clock(), channel()
    a = make(ch, clock, ident=1, addr=0x80, **kw)
    b = make(ch, clock, ident=2, addr=0x81, **kw)
    got: list[Message] = []
    b.handlers.append(got.append)
    a.start()
    b.start()
    settle([a, b], clock)
    return clock, a, b, got


@pytest.mark.parametrize("size", [9, 100, 1785, 1786, 12_345, 70_000])
def test_tp_and_etp_round_trip(size):
    clock, a, b, got = _pair()
    payload = bytes(random.Random(size).randrange(256) for _ in range(size))
    tx = a.send(0xCB00, payload, da=b.address)
    pump([a, b])
    assert tx is not None and tx.done.is_set() and tx.ok, tx.error if tx else None
    assert len(got) == 1 and got[0].data == payload and got[0].sa == a.address
    assert got[0].pgn == 0xCB00


def test_bam_broadcast_is_paced():
    clock, a, b, got = _pair()
    payload = bytes(range(40))
    tx = a.send(0xFECA, payload)
    assert tx is not None
    pump([a, b])
    assert not got  # the packets wait for the 50 ms gap
    settle([a, b], clock, 0.5)
    assert tx.ok and got and got[0].data == payload


def test_malformed_and_unexpected_frames_never_raise():
    clock, a, b, got = _pair()
    junk = [
        (encode_id(0xEC00, 0x33, b.address), b"\x10\x01"),  # short CM
        (encode_id(0xEC00, 0x33, b.address), b"\x10\xff\xff\x05\xff\x00\xcb\x00"),  # size > 1785
        (encode_id(0xEB00, 0x33, b.address), b"\x01" + b"\x00" * 7),  # DT without session
        (encode_id(0xC800, 0x33, b.address), b"\x16\x05\x00\x00\x00\x00\xcb\x00"),  # DPO, no RTS
        (encode_id(0xEE00, 0x33, 0xFF), b"\x01"),  # short claim
        (encode_id(0xEA00, 0x33, 0xFF), b""),  # empty request
    ]
    for cid, data in junk:
        b.handle_frame(can.Message(arbitration_id=cid, data=data, is_extended_id=True))
    b.handle_frame(can.Message(arbitration_id=0x123, data=b"\x00", is_extended_id=False))
    pump([a, b])
    assert b.stats.malformed >= 4
    assert not got


def test_bad_sequence_aborts_and_sender_fails():
    clock, a, b, got = _pair()
    payload = bytes(100)
    # sender side: a CTS answered by a receiver that then aborts
    tx = a.send(0xCB00, payload, da=b.address)
    b.poll(0.0)  # b takes the RTS and answers CTS; then an out-of-order DT arrives
    b.handle_frame(
        can.Message(
            arbitration_id=encode_id(0xEB00, a.address, b.address, 7),
            data=b"\x05" + b"\x00" * 7,
            is_extended_id=True,
        )
    )
    pump([a, b])
    assert tx is not None and tx.done.is_set()
    assert b.stats.aborts_tx == 1 and not tx.ok and "aborted" in tx.error
    assert not got


def test_send_on_a_dead_bus_is_an_alarm_not_a_crash():
    clock, a, b, got = _pair()
    a.bus.shutdown()
    for _ in range(3):
        a.send(0xCB00, bytes(8), da=b.address)
    assert "isobus_bus_off" in a.alarms and a.stats.tx_errors == 3
    a.poll(0.0)  # receiving on a closed bus is also survived


def test_bus_off_error_frame_raises_the_alarm():
    clock, a, b, got = _pair()
    b.handle_frame(can.Message(arbitration_id=0x40, is_error_frame=True, data=bytes(8)))
    assert "isobus_bus_off" in b.alarms and b.stats.error_frames == 1 and not b.bus_ok
    # the next successful send clears it
    b.send(0xCB00, bytes(8), da=a.address)
    assert "isobus_bus_off" not in b.alarms and b.bus_ok


def test_transfer_to_a_silent_node_times_out():
    clock, a, b, got = _pair()
    tx = a.send(0xCB00, bytes(5000), da=0x99)  # nobody at 0x99: no CTS ever comes
    settle([a, b], clock, 1.0)
    assert tx is not None and not tx.done.is_set()
    settle([a, b], clock, 0.5)
    assert tx.done.is_set() and not tx.ok and tx.error == "timeout"
    assert a.stats.aborts_tx == 1


def test_receiver_drops_a_transfer_whose_data_stops():
    clock, a, b, got = _pair()
    rts = b"\x10" + (100).to_bytes(2, "little") + bytes((15, 0xFF)) + b"\x00\xcb\x00"
    b.handle_frame(
        can.Message(
            arbitration_id=encode_id(0xEC00, a.address, b.address, 7), data=rts, is_extended_id=True
        )
    )
    assert b.open_transfers == (1, 0)  # session open, CTS sent
    settle([b], clock, 1.5)
    assert b.open_transfers == (0, 0) and b.stats.aborts_tx == 1 and not got
