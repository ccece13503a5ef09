"""Every packet of a nominal run and of a fault run, read by an independent PUS-C reader (tests/contracts/
pus_c_reader.py, written from the standards), conforms to ECSS-E-ST-70-41C as the mission uses it."""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import pytest

from tests.contracts import pus_c_reader as rd
from tests.integration.conftest import DATA, flyby

pytestmark = pytest.mark.integration

ACCEPTANCE, START, COMPLETION = 0b0001, 0b0010, 0b1000  # ECSS-E-ST-70-41C ack flags: bit 3 (lowest) is acceptance
SUCCESS_SUBTYPE = {ACCEPTANCE: 1, START: 3, COMPLETION: 7}


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The short slice with a fault campaign: link outage, star tracker outage, lost frames, a clock jump."""
    out = tmp_path_factory.mktemp("runs") / "faults"
    r = flyby("run", str(DATA / "short-faults.yaml"), "--out", str(out), timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return out


class RunPackets:
    """A run's telemetry and telecommands as the independent reader sees them."""

    def __init__(self, run: Path) -> None:
        self.tm = [rd.tm(p) for p in rd.split((run / "tm.bin").read_bytes())]
        self.radiated = [rd.tc(p) for p in rd.split((run / "tc.bin").read_bytes())]
        self.sent: dict[bytes, rd.Tc] = {}  # every TC ground sent, by request id, the scheduled ones included
        for t in self.radiated:
            self.sent[t.request_id] = t
            if (t.service, t.subtype) == (11, 4):
                self.sent.update((e.request_id, e) for _, e in rd.insert_activities(t.data))
            if (t.service, t.subtype) == (200, 8):
                self.sent.update((e.request_id, e) for _, _, e in rd.ca_relative_activities(t.data))


def _check(run: Path, lossless: bool) -> RunPackets:
    """Every rule of the conformance test on one run folder (the reader itself checks headers and CRCs);
    ``lossless``: no telemetry was lost on the link, so every report asked for is there."""
    p = RunPackets(run)
    assert p.tm and p.radiated
    # radiated TCs count on without gaps: scheduled TCs do not consume the radiated sequence
    counts = [t.primary.seq_count for t in p.radiated]
    assert counts == list(range(counts[0], counts[0] + len(counts))), counts
    # every TM has a time reference status and a destination
    assert all(m.time_status != 0 for m in p.tm)
    assert all(m.destination_id != 0 for m in p.tm)
    # one message type counter per (service, subtype, destination): the packets each one misses are the packets the
    # sequence count misses (a lost packet is missing from both, nothing else is)
    last: dict[tuple[int, int, int], int] = {}
    missed_by_counters = 0
    for m in p.tm:
        key = (m.service, m.subtype, m.destination_id)
        step = m.message_counter - last[key] - 1 if key in last else m.message_counter
        assert step >= 0, f"{key}: counter went from {last.get(key)} to {m.message_counter}"
        missed_by_counters += step
        last[key] = m.message_counter
    seq = [m.primary.seq_count for m in p.tm]
    missed_by_seq = seq[0] + sum(b - a - 1 for a, b in zip(seq, seq[1:]))
    assert missed_by_counters == missed_by_seq
    # verification reports: about TCs ground sent, to their source, success reports exactly as the ack flags ask
    reports: dict[bytes, list[rd.Tm]] = defaultdict(list)
    for m in p.tm:
        if m.service == 1:
            reports[m.data[:4]].append(m)
    assert reports
    for rid, got in reports.items():
        assert rid in p.sent, f"verification of a TC ground never sent: {rid.hex()}"
        t = p.sent[rid]
        assert all(m.destination_id == t.source_id for m in got)
        subtypes = [m.subtype for m in got]
        successes = [k for k in subtypes if k % 2]
        asked = [SUCCESS_SUBTYPE[f] for f in (ACCEPTANCE, START, COMPLETION) if t.ack_flags & f]
        if successes == subtypes:  # executed: the successes asked for, in stage order, and no other
            assert successes == asked if lossless else set(successes) <= set(asked), (rid.hex(), subtypes, asked)
        else:  # one failure, after the successes asked for of the stages before it
            failure = [k for k in subtypes if not k % 2]
            assert len(failure) == 1 and subtypes[-1] == failure[0], (rid.hex(), subtypes)
            before = [k for k in asked if k < failure[0] - 1]
            assert successes == before if lossless else set(successes) <= set(before), (rid.hex(), subtypes)
    # the time report rate is the one TC[9,1] set, or 0 (one a second) for the mission's TC[200,6] bursts
    rates = {t.data[0] for t in p.sent.values() if (t.service, t.subtype) == (9, 1)}
    bursts = {0} if any((t.service, t.subtype) == (200, 6) for t in p.sent.values()) else set()
    time_reports = [m for m in p.tm if (m.service, m.subtype) == (9, 2)]
    assert rates and time_reports
    assert rates <= {m.data[0] for m in time_reports} <= rates | bursts
    assert all(abs(rd.cuc_seconds(m.data, 1) - m.time_s) < 2**-15 for m in time_reports)
    return p


def test_nominal_run_conforms(short_runs: tuple[Path, Path]) -> None:
    """Every TM and TC of the nominal run passes the independent PUS-C reader and its rules; start reports come."""
    p = _check(short_runs[0], lossless=True)
    assert any((m.service, m.subtype) == (1, 3) for m in p.tm), "no TM[1,3] start report"
    assert any((t.service, t.subtype) == (200, 8) for t in p.radiated), "no C/A-relative insert TC[200,8]"


def test_fault_run_conforms(fault_run: Path) -> None:
    """The fault run too, with telemetry lost in the link outage and packets stamped across the clock jump; its
    timeline's absolute tag goes up in a standard TC[11,4]."""
    p = _check(fault_run, lossless=False)
    assert any((t.service, t.subtype) == (11, 4) for t in p.radiated), "no TC[11,4]"
    seq = [m.primary.seq_count for m in p.tm]
    assert any(b - a > 1 for a, b in zip(seq, seq[1:])), "the link outage lost no telemetry"
    assert {m.time_status for m in p.tm} == {1, 2}, "no packet stamped in the period of the clock jump"


def test_every_service_of_the_runs_is_in_the_service_table(short_runs: tuple[Path, Path], fault_run: Path) -> None:
    """The dictionary's service table lists every (service, subtype) the runs sent, service 200's included."""
    table = flyby("dictionary").stdout.split("## Services\n", 1)[1].split("\n## ", 1)[0]
    listed = set()
    for service, tcs, tms in re.findall(r"^\| (\d+) \|[^|]*\|([\d, ]*)\|([\d, ]*)\|$", table, re.M):
        listed |= {(int(service), int(k)) for k in (tcs + "," + tms).split(",") if k.strip()}
    for run in (short_runs[0], fault_run):
        p = RunPackets(run)
        seen = {(m.service, m.subtype) for m in p.tm} | {(t.service, t.subtype) for t in p.sent.values()}
        assert seen <= listed, seen - listed
        assert any(s == 200 for s, _ in seen)
