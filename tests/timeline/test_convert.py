"""Resolution of timeline tags to on-board time: closed forms, cumulative chaining, tag order."""

from __future__ import annotations

import calendar
import math
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ground.correlation import Correlation
from timeline.convert import epoch_datetime, resolved_commands, utc_seconds
from timeline.model import (
    AfterPreviousTag,
    CaTag,
    ObtTag,
    Timeline,
    TimelineEntry,
    TimelineError,
    UtcTag,
    default_registry,
)
from timeline.parse import load_timeline

EPOCH = "2022-09-26T23:14:24Z"
UTC = timezone.utc
EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "timelines" / "flyby-imaging.yaml"
REG = default_registry()

# OBT counts from launch: about 2.65e7 s at the flyby (universe OscillatorConfig.initial_offset_s).
offsets = st.floats(min_value=-1e6, max_value=5e7, allow_nan=False)
drifts = st.floats(min_value=-1e-3, max_value=1e-3, allow_nan=False)  # +-1000 ppm, far beyond any oscillator
ca_utcs = st.floats(min_value=-1e5, max_value=1e5, allow_nan=False)
ca_offsets = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)
delays = st.floats(min_value=0, max_value=1e4, allow_nan=False)
utc_datetimes = st.datetimes(min_value=datetime(2022, 9, 20), max_value=datetime(2022, 10, 3), timezones=st.just(UTC))


def _entry(tag: object, name: str = "stop_imaging") -> TimelineEntry:
    """A timeline entry of a no-argument command."""
    return TimelineEntry(tag=tag, command=REG.command(name))  # type: ignore[arg-type]


def _seconds_after_epoch(dt: datetime) -> float:
    """Seconds from the epoch by calendar arithmetic (independent of datetime subtraction)."""
    epoch = calendar.timegm((2022, 9, 26, 23, 14, 24, 0, 0, 0))
    return (calendar.timegm(dt.utctimetuple()) - epoch) + dt.microsecond / 1e6


def _close(a: float, b: float, scale: float) -> bool:
    """a and b agree to float rounding at magnitude ``scale``."""
    return abs(a - b) <= 8 * np.finfo(float).eps * max(1.0, scale)


@given(offsets, drifts, utc_datetimes)
@settings(max_examples=100)
def test_utc_tag_resolves_to_the_linear_correlation(offset: float, drift: float, when: datetime) -> None:
    """A UTC tag resolves to offset + (1 + drift) * seconds after the epoch."""
    out = resolved_commands(Timeline(entries=(_entry(UtcTag(utc=when)),)), Correlation.exact(offset, drift),
                            epoch_utc=EPOCH)
    u = _seconds_after_epoch(when)
    assert out[0].ca_offset_s is None
    assert _close(out[0].obt_s, offset + (1 + drift) * u, abs(offset) + abs(u))


@given(offsets, drifts, ca_utcs, ca_offsets)
@settings(max_examples=100)
def test_ca_tag_resolves_to_ca_obt_plus_offset(offset: float, drift: float, ca_utc: float, ca_off: float) -> None:
    """A C/A tag resolves to OBT(C/A estimate) + offset and keeps its offset for on-board re-anchoring."""
    out = resolved_commands(Timeline(entries=(_entry(CaTag(ca_offset_s=ca_off)),)), Correlation.exact(offset, drift),
                            epoch_utc=EPOCH, ca_utc_s=ca_utc)
    expected = offset + (1 + drift) * ca_utc + ca_off
    assert _close(out[0].obt_s, expected, abs(offset) + abs(ca_utc) + abs(ca_off))
    assert out[0].ca_offset_s == ca_off


@given(offsets, drifts, st.floats(min_value=-1e9, max_value=1e9, allow_nan=False))
@settings(max_examples=50)
def test_obt_tag_is_independent_of_the_correlation(offset: float, drift: float, obt: float) -> None:
    """An OBT tag resolves to itself whatever the correlation."""
    out = resolved_commands(Timeline(entries=(_entry(ObtTag(obt_s=obt)),)), Correlation.exact(offset, drift),
                            epoch_utc=EPOCH)
    assert out[0] == (obt, None, REG.command("stop_imaging"), 1)


@given(
    offsets,
    drifts,
    st.one_of(st.builds(ObtTag, obt_s=st.floats(-1e6, 1e6)), st.builds(CaTag, ca_offset_s=ca_offsets)),
    st.lists(delays, min_size=1, max_size=10),
    ca_utcs,
)
@settings(max_examples=100)
def test_relative_chain_is_cumulative(
    offset: float, drift: float, anchor: ObtTag | CaTag, chain: list[float], ca_utc: float
) -> None:
    """The k-th '+d' after an anchor resolves to anchor + d1 + ... + dk, tied to C/A iff the anchor is."""
    tl = Timeline(entries=(_entry(anchor), *(_entry(AfterPreviousTag(delay_s=d)) for d in chain)))
    corr = Correlation.exact(offset, drift)
    out = resolved_commands(tl, corr, epoch_utc=EPOCH, ca_utc_s=ca_utc)
    anchor_obt = anchor.obt_s if isinstance(anchor, ObtTag) else offset + (1 + drift) * ca_utc + anchor.ca_offset_s
    scale = abs(offset) + abs(ca_utc) + 1e6 + sum(chain)
    for k, r in enumerate(out):
        assert _close(r.obt_s, anchor_obt + math.fsum(chain[:k]), scale)
        if isinstance(anchor, CaTag):
            assert r.ca_offset_s is not None
            assert _close(r.ca_offset_s, anchor.ca_offset_s + math.fsum(chain[:k]), scale)
        else:
            assert r.ca_offset_s is None


mixed_tags = st.one_of(
    st.builds(UtcTag, utc=utc_datetimes),
    st.builds(ObtTag, obt_s=st.floats(-1e6, 1e6)),
    st.builds(AfterPreviousTag, delay_s=delays),
    st.builds(CaTag, ca_offset_s=ca_offsets),
)


@given(offsets, drifts, ca_utcs, st.lists(mixed_tags, min_size=1, max_size=12))
@settings(max_examples=100)
def test_resolved_order_is_tag_order(offset: float, drift: float, ca_utc: float, tag_list: list[object]) -> None:
    """Resolved commands come out sorted by OBT, all present, equal tags in file order, each with its file row."""
    if isinstance(tag_list[0], AfterPreviousTag):
        tag_list[0] = ObtTag(obt_s=0.0)
    # report_time(count=row) marks each entry with its file row.
    tl = Timeline(entries=tuple(
        TimelineEntry(tag=t, command=REG.command("report_time", {"count": i + 1}))  # type: ignore[arg-type]
        for i, t in enumerate(tag_list)
    ))
    out = resolved_commands(tl, Correlation.exact(offset, drift), epoch_utc=EPOCH, ca_utc_s=ca_utc)
    rows = [r.command.args["count"] for r in out]
    assert sorted(rows) == list(range(1, len(tag_list) + 1))
    assert [r.row for r in out] == rows
    for a, b, ra, rb in zip(out, out[1:], rows, rows[1:]):
        assert a.obt_s < b.obt_s or (a.obt_s == b.obt_s and ra < rb)


@given(offsets, drifts, ca_utcs, st.floats(-1e3, 1e3), st.lists(mixed_tags, min_size=1, max_size=8))
@settings(max_examples=60)
def test_new_ca_estimate_moves_only_ca_tied_commands(
    offset: float, drift: float, ca_utc: float, shift: float, tag_list: list[object]
) -> None:
    """Moving the C/A estimate by s moves each C/A-tied command by (1 + drift) s and no other."""
    if isinstance(tag_list[0], AfterPreviousTag):
        tag_list[0] = CaTag(ca_offset_s=0.0)
    tl = Timeline(entries=tuple(
        TimelineEntry(tag=t, command=REG.command("report_time", {"count": i + 1}))  # type: ignore[arg-type]
        for i, t in enumerate(tag_list)
    ))
    corr = Correlation.exact(offset, drift)
    before = {r.command.args["count"]: r for r in resolved_commands(tl, corr, epoch_utc=EPOCH, ca_utc_s=ca_utc)}
    after = {r.command.args["count"]: r for r in resolved_commands(tl, corr, epoch_utc=EPOCH, ca_utc_s=ca_utc + shift)}
    scale = abs(offset) + abs(ca_utc) + 1e6 + 1e5
    for row, b in before.items():
        a = after[row]
        assert a.ca_offset_s == b.ca_offset_s
        moved = (1 + drift) * shift if b.ca_offset_s is not None else 0.0
        assert _close(a.obt_s - b.obt_s, moved, scale)


def test_example_fast_cadence_window_is_centred_on_ca() -> None:
    """In the shipped timeline the fast-cadence window is centred on the C/A estimate, in OBT."""
    corr = Correlation.exact(2.5, 40e-6)
    ca_utc = 168.0
    out = resolved_commands(load_timeline(EXAMPLE), corr, epoch_utc=EPOCH, ca_utc_s=ca_utc)
    cadence = [r for r in out if r.command.name == "set_camera_cadence"]
    fast, slow = cadence
    assert fast.command.args["period_s"] < slow.command.args["period_s"]
    assert (fast.obt_s + slow.obt_s) / 2 == pytest.approx(corr.to_obt(ca_utc), abs=1e-9)
    assert [r.command.name for r in out][0] == "set_mode" and out[-1].command.args == {"mode": "STANDBY"}


def test_ca_tag_without_estimate_names_the_row() -> None:
    """Resolving a C/A tag without a C/A estimate is refused, naming the row and its followers."""
    tl = Timeline(entries=(_entry(ObtTag(obt_s=1.0)), _entry(CaTag(ca_offset_s=-5.0)),
                           _entry(AfterPreviousTag(delay_s=1.0))))
    with pytest.raises(TimelineError) as err:
        resolved_commands(tl, Correlation.exact(0.0, 0.0), epoch_utc=EPOCH)
    assert err.value.problems == [
        "row 2, field 'time': tied to C/A but no C/A estimate (ca_utc_s) was given",
        "row 3, field 'time': relative to row 2, which could not be resolved",
    ]


def test_tags_before_the_earliest_allowed_obt_are_refused() -> None:
    """Every command resolving before not_before_obt_s is refused with its OBT and the limit."""
    tl = Timeline(entries=(_entry(ObtTag(obt_s=99.0)), _entry(ObtTag(obt_s=100.0)),
                           _entry(AfterPreviousTag(delay_s=0.0)), _entry(CaTag(ca_offset_s=-70.0))))
    with pytest.raises(TimelineError) as err:
        resolved_commands(tl, Correlation.exact(0.0, 0.0), epoch_utc=EPOCH, ca_utc_s=168.0, not_before_obt_s=100.0)
    assert err.value.problems == [
        "row 1, field 'time': resolves to OBT 99.000 s, before the earliest allowed OBT 100.000 s",
        "row 4, field 'time': resolves to OBT 98.000 s, before the earliest allowed OBT 100.000 s",
    ]
    ok = resolved_commands(tl, Correlation.exact(0.0, 0.0), epoch_utc=EPOCH, ca_utc_s=170.0, not_before_obt_s=99.0)
    assert [r.obt_s for r in ok] == [99.0, 100.0, 100.0, 100.0]


def test_epoch_must_be_a_zoned_iso_time() -> None:
    """An epoch without a zone or not ISO 8601 is refused naming epoch_utc."""
    with pytest.raises(ValueError, match="epoch_utc: .* must carry its zone"):
        epoch_datetime("2022-09-26T23:14:24")
    with pytest.raises(ValueError, match="epoch_utc: cannot read 'yesterday'"):
        epoch_datetime("yesterday")
    assert utc_seconds(datetime(2022, 9, 26, 23, 15, 24, 500000, tzinfo=UTC), EPOCH) == 60.5
