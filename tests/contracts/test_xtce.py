"""XTCE export: ``flyby dictionary --xtce`` is read by an independent XTCE reader (tests/contracts/xtce_reader.py)
into the same values as the project's decoder, for every packet of a nominal run and for every TM packet type."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from contracts import pus
from contracts.dictionary import DICTIONARY, EventReport
from contracts.packet import Record, RecordWire, Validity
from contracts.wire import CountedList, CucWire, EmbeddedPacket, EnumCode, Padded, RequestIdWire, Vector, WireType
from flyby.cli import main
from flyby.inprocess import run_in_process
from scenario.model import load_run_inputs
from tests.contracts.strategies import apids, counters, grid_obt, packet_strategy, seqs
from tests.contracts.xtce_reader import XtceReader

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def xtce_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The XTCE document written by ``flyby dictionary --xtce``."""
    out = tmp_path_factory.mktemp("xtce") / "flyby.xml"
    assert main(["dictionary", "--xtce", str(out)]) == 0
    return out


@pytest.fixture(scope="session")
def reader(xtce_file: Path) -> XtceReader:
    """The independent reader of that document."""
    return XtceReader(xtce_file)


@pytest.fixture(scope="session")
def nominal_tm_bin() -> bytes:
    """The tm.bin of the nominal scenario: every received TM packet's octets, in order (as the archive writes)."""
    run = run_in_process(*load_run_inputs(ROOT / "configs/scenarios/nominal.yaml"))
    return b"".join(p.raw for p in run.received)


def _expected(prefix: str, wire: WireType, value: Any, out: dict[str, list[Any]]) -> None:
    """The XTCE parameters one field becomes, by the export's naming rules, with the decoder's values."""
    if isinstance(wire, Vector | Padded):
        for i, v in enumerate(value):
            _expected(f"{prefix}_{i}", wire.element, v, out)
    elif isinstance(wire, CucWire):
        out.setdefault(f"{prefix}_coarse", []).append(math.floor(value))
        out.setdefault(f"{prefix}_fine", []).append(round((value - math.floor(value)) * 65536))
    elif isinstance(wire, RequestIdWire):
        out.setdefault(f"{prefix}_apid", []).append(value.apid)
        out.setdefault(f"{prefix}_sequence_count", []).append(value.seq_count)
    elif isinstance(wire, CountedList) and isinstance(wire.element, RecordWire):
        out.setdefault(f"{prefix}_count", []).append(len(value))
        for item in value:
            _record(f"{prefix}_item", item, out)
    elif isinstance(wire, EmbeddedPacket):
        out.setdefault(f"{prefix}_length", []).append(len(value) - 7)
        out.setdefault(f"{prefix}_rest", []).append(list(value[7:]))
    else:
        out.setdefault(prefix, []).append(int(value) if isinstance(wire, EnumCode) else value)


def _record(prefix: str, value: Record, out: dict[str, list[Any]], left_out: tuple[str, ...] = ()) -> None:
    for it in type(value).LAYOUT:
        if it.is_field and it.name not in left_out and getattr(value, it.name) is not None:
            _expected(f"{prefix}_{it.name}", it.wire, getattr(value, it.name), out)


def _flags_agree(name: str, report: Record, got: dict[str, list[Any]]) -> None:
    """Each optional field's validity bit, as read by the reader, says whether the decoder found it."""
    flags = next((f"{name}_{it.name}" for it in type(report).LAYOUT if isinstance(it.extra, Validity)), None)
    for it in type(report).LAYOUT:
        if it.bit is not None and flags is not None:
            assert bool(got[flags][0] >> it.bit & 1) == (getattr(report, it.name) is not None), (name, it.name)


def _check(reader: XtceReader, raw: bytes) -> str:
    """Decode ``raw`` both ways and compare header and fields; return the container name."""
    header, report = pus.decode_tm(raw)
    name, got = reader.decode(raw)
    assert name == type(report).__name__
    assert got["ccsds_apid"] == [header.apid] and got["ccsds_sequence_count"] == [header.seq_count]
    assert got["ccsds_length"] == [len(raw) - 7] and got["ccsds_type"] == [0]
    assert (got["pus_service"], got["pus_subtype"]) == ([header.service], [header.subservice])
    assert (got["pus_message_counter"], got["pus_destination_id"]) == ([header.msg_counter], [header.destination_id])
    assert got["pus_obt_p_field"] == [0x2E]
    assert got["pus_obt_coarse"][0] + got["pus_obt_fine"][0] / 65536 == header.obt_s
    if isinstance(report, EventReport):
        assert got["event_id"] == [int(report.EVENT_ID)]
    want: dict[str, list[Any]] = {}
    left_out = type(report).VARIANTS.get(header.subservice, ())
    _record(name, report, want, left_out)
    for param, values in want.items():
        assert repr(got.get(param)) == repr(values), (name, param, got.get(param), values)  # NaN equals NaN
    for field in left_out:  # a field the subtype leaves out is no entry of the packet
        assert not any(p.startswith(f"{name}_{field}") for p in got), (name, field)
    _flags_agree(name, report, got)
    return name


def test_nominal_run_reads_the_same_through_xtce(reader: XtceReader, nominal_tm_bin: bytes) -> None:
    """Every packet of the nominal tm.bin decodes through the XTCE containers to the values decode_tm gives."""
    names = [_check(reader, raw) for raw in pus.split_packets(nominal_tm_bin)]
    kinds = set(names)
    assert len(names) > 1000
    assert {"Housekeeping", "NavigationReport", "EstimateReport", "TimeReport", "Verification",
            "ModeChangedEvent"} <= kinds


@pytest.mark.parametrize("packet", [p for p in DICTIONARY.packets if p.KIND == "TM"], ids=lambda p: p.__name__)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), apid=apids, seq=seqs, obt_s=grid_obt, counter=counters)
def test_every_report_reads_the_same_through_xtce(reader: XtceReader, packet: type, data: st.DataObject, apid: int,
                                                  seq: int, obt_s: float, counter: int) -> None:
    """Values of every TM packet of the dictionary decode through the XTCE containers as through decode_tm."""
    raw = pus.encode_tm(data.draw(packet_strategy(packet)), apid, seq, obt_s, counter)
    assert _check(reader, raw) == packet.__name__


def test_xtce_states_the_obt_epoch(xtce_file: Path) -> None:
    """The time descriptions say what OBT counts from: the CUC's agency epoch and the oscillator offset."""
    text = xtce_file.read_text(encoding="utf-8")
    assert "agency-defined epoch" in text and "universe.oscillator.initial_offset_s" in text
