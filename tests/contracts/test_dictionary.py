"""The TM/TC dictionary: every declared packet round-trips through the codec, and what is derived from the
declarations (documentation, timeline commands) covers every packet."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from contracts import pus
from contracts.dictionary import DICTIONARY
from contracts.dictionary_doc import markdown, packet_id
from contracts import packet as packet_module
from contracts.packet import Packet
from contracts.wire import Reader
from tests.contracts.strategies import apids, counters, grid_obt, packet_strategy, seqs
from timeline.model import STANDARD_COMMANDS

_SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
PACKETS = DICTIONARY.packets


@pytest.mark.parametrize("packet", PACKETS, ids=[p.__name__ for p in PACKETS])
@_SETTINGS
@given(data=st.data(), apid=apids, seq=seqs, obt_s=grid_obt, counter=counters)
def test_every_packet_round_trips(packet: type[Packet], data: st.DataObject, apid: int, seq: int, obt_s: float,
                                  counter: int) -> None:
    """decode(encode(value)) gives back the value and its header, for values of every packet drawn from its
    declaration; the subtype is one the packet declares."""
    value = data.draw(packet_strategy(packet))
    assert value.subservice() in packet.SUBTYPES
    if packet.KIND == "TC":
        header, back = pus.decode_tc(pus.encode_tc(value, apid, seq))
        assert (header.apid, header.seq_count) == (apid, seq)
    else:
        header, back = pus.decode_tm(pus.encode_tm(value, apid, seq, obt_s, counter))
        assert (header.apid, header.seq_count, header.obt_s, header.msg_counter) == (apid, seq, obt_s, counter)
    assert back == value and type(back) is packet
    assert (header.service, header.subservice) == (packet.SERVICE, value.subservice())


def test_every_subtype_decodes_to_one_packet() -> None:
    """No two packets of one kind claim the same (service, subtype), nor two events the same event id."""
    tc = [(p.SERVICE, s) for p in PACKETS if p.KIND == "TC" for s in p.SUBTYPES]
    tm = [(p.SERVICE, s) for p in PACKETS if p.KIND == "TM" and p.SERVICE != 5 for s in p.SUBTYPES]
    events = [int(p.EVENT_ID) for p in PACKETS if p.SERVICE == 5]
    for claimed in (tc, tm, events):
        assert len(claimed) == len(set(claimed))
    assert len(DICTIONARY.telecommands) + len(DICTIONARY.reports) + len(DICTIONARY.events) == len(tc + tm + events)


def test_documentation_lists_every_packet_and_field() -> None:
    """The generated Markdown has a summary row and a section for each packet, naming each of its fields."""
    doc = markdown()
    for p in PACKETS:
        assert f"| {p.KIND} | {packet_id(p)} | {p.__name__} |" in doc
        section = doc.split(f"## {packet_id(p)} {p.__name__}\n", 1)[1].split("\n## ", 1)[0]
        for it in p.LAYOUT:
            assert f"| {it.name} |" in section or f"| *{it.name}* |" in section, (p.__name__, it.name)


def test_documentation_gives_offsets_of_fixed_layouts() -> None:
    """A fixed layout's offsets add up its fields' sizes: housekeeping's best-grid MSE starts at octet 81, the TC
    security counters at 85, the executive's skipped releases at 195 and its last field at octet 219 of 221."""
    doc = markdown()
    section = doc.split("## TM[3,25] Housekeeping\n", 1)[1].split("\n## ", 1)[0]
    assert "| 81 | best_mse_rad2 | f32 | rad^2 |" in section
    assert "| 89 | tc_rejected_replay | u16 |" in section
    assert "| 195 | skipped_releases | u32 |" in section
    assert "| 219 | measurements_rejected | u16 |" in section
    assert pus.HK_SIZE == 221


def test_timeline_commands_are_the_dictionarys() -> None:
    """Each standard timeline command sends a telecommand of the dictionary and checks its arguments with the
    telecommand's own bounds (the fields ground fills are not arguments)."""
    by_name = {c.name: c for c in STANDARD_COMMANDS}
    assert set(by_name) == set(DICTIONARY.commands)
    for name, packet in DICTIONARY.commands.items():
        args = by_name[name].arguments.model_fields
        fills = packet.COMMAND.ground_fills  # type: ignore[union-attr]
        assert set(args) == set(packet.model_fields) - set(fills)
        for field, info in args.items():
            assert info.metadata == packet.model_fields[field].metadata, (name, field)


def _item_by_item(fn, *args):  # type: ignore[no-untyped-def]
    """``fn(*args)`` with the codec's one-struct fast path off: its result, or the error it raised."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(packet_module, "_fixed_plan", lambda layout, left_out: None)
        try:
            return fn(*args)
        except pus.PacketError as exc:
            return repr(exc)


def _outcome(fn, *args):  # type: ignore[no-untyped-def]
    try:
        return fn(*args)
    except pus.PacketError as exc:
        return repr(exc)


@pytest.mark.parametrize("packet", PACKETS, ids=[p.__name__ for p in PACKETS])
@_SETTINGS
@given(data=st.data())
def test_one_struct_codec_equals_item_by_item(packet: type[Packet], data: st.DataObject) -> None:
    """The fast path of fixed layouts gives the octets and values of the item-by-item codec: for values drawn from
    the declaration, and for the same octets with random changes (the same value, or the same error)."""
    value = data.draw(packet_strategy(packet))
    octets = value.app_data()
    assert octets == _item_by_item(value.app_data)
    sub = value.subservice()
    mutated = bytearray(octets)
    for pos in data.draw(st.lists(st.integers(0, max(len(octets) - 1, 0)), max_size=3)) if octets else []:
        mutated[pos] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(mutated)))
    for raw in (octets, bytes(mutated), bytes(mutated[:cut])):
        def read(raw: bytes = raw) -> Packet:
            r = Reader(raw, packet.__name__)
            got = packet.from_app_data(sub, r)
            r.end()
            return got
        # by repr: a NaN field (a corrupted float) is equal to itself there, as its octets are
        assert repr(_outcome(read)) == repr(_item_by_item(read))
