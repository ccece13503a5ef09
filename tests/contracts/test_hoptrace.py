"""Hop traces: marks written and read back, and the chain's links timed as the differences of their marks."""

from __future__ import annotations

from pathlib import Path

import pytest

from contracts.hoptrace import CHAIN, NEXT_REQUEST, HopTrace, Mark, TraceError, hop_table, read_traces


def _period(step: int, start_ns: int, gaps_ns: list[int]) -> list[Mark]:
    """The chain's marks of one period, the k-th link lasting ``gaps_ns[k]``."""
    t, marks = start_ns, []
    for (node, what), gap in zip(CHAIN, [0, *gaps_ns]):
        t += gap
        marks.append(Mark(t, node, what, step))
    return marks


def test_each_link_lasts_the_difference_of_its_marks() -> None:
    """Three periods with known gaps: every link's durations, the time to the next request, and nothing else."""
    n = len(CHAIN) - 1
    gaps = [[1000 * (k + 1) + 10 * p for k in range(n)] for p in range(3)]
    marks: list[Mark] = []
    starts = [0, 10_000_000, 25_000_000]
    for p, start in enumerate(starts):
        marks += _period(p, start, gaps[p])
    # a ground exchange and a resent request: neither is a link of the chain, nor moves the first marks
    marks += [Mark(5, "ground", "work", 0), Mark(starts[1] + 999_999, "universe", CHAIN[0][1], 1)]
    table = hop_table(sorted(marks, key=lambda m: m.t_ns))
    assert [s.name for s in table][-1] == NEXT_REQUEST and len(table) == n + 1
    for k, seg in enumerate(table[:-1]):
        assert seg.durations_s == pytest.approx([gaps[p][k] * 1e-9 for p in range(3)], abs=1e-15)
    ends = [s + sum(g) for s, g in zip(starts, gaps)]
    assert table[-1].durations_s == pytest.approx([(starts[1] - ends[0]) * 1e-9, (starts[2] - ends[1]) * 1e-9])
    assert table[0].median_us == pytest.approx(gaps[1][0] * 1e-3)
    assert table[0].total_s == pytest.approx(sum(g[0] for g in gaps) * 1e-9)


def test_a_period_missing_a_mark_is_left_out() -> None:
    """A period without its reply's arrival (the run ended, a node was killed) is not counted."""
    marks = _period(0, 0, [100] * (len(CHAIN) - 1)) + _period(1, 10_000, [100] * (len(CHAIN) - 1))[:9]
    assert {len(s.durations_s) for s in hop_table(marks)} == {1}


def test_marks_written_are_read_back_in_time_order(tmp_path: Path) -> None:
    """Two nodes' files read together give every mark, sorted by time."""
    a, b = HopTrace("universe", tmp_path / "u.csv"), HopTrace("obsw", tmp_path / "o.csv")
    a.mark_at(300, "work", 2)
    b.mark_at(100, "publish:obsw/reply", 1)
    a.mark_at(200, "taken:obsw/reply", 1)
    a.write()
    b.write()
    assert read_traces([tmp_path / "u.csv", tmp_path / "o.csv"]) == [
        Mark(100, "obsw", "publish:obsw/reply", 1), Mark(200, "universe", "taken:obsw/reply", 1),
        Mark(300, "universe", "work", 2)]


def test_a_file_that_is_not_a_trace_is_named(tmp_path: Path) -> None:
    """A foreign file, or a damaged line, is refused naming the file and the line."""
    (tmp_path / "x.csv").write_text("a,b\n")
    with pytest.raises(TraceError, match="x.csv: not a hop trace"):
        read_traces([tmp_path / "x.csv"])
    (tmp_path / "y.csv").write_text("t_ns,node,what,step\n1,obsw,work,1\n2,obsw,work\n")
    with pytest.raises(TraceError, match="y.csv: line 3: 3 fields"):
        read_traces([tmp_path / "y.csv"])
