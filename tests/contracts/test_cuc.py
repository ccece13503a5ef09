"""CCSDS CUC time code for OBT: layout, exact round trip on the tick grid, rounding bound, range errors."""

from __future__ import annotations

import math
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from contracts.cuc import (
    CUC_LEN,
    MAX_COARSE,
    MAX_OBT_S,
    P_FIELD,
    TICK_S,
    CucFormatError,
    CucRangeError,
    cuc_decode,
    cuc_encode,
    cuc_from_ticks,
    obt_from_ticks,
    ticks_from_cuc,
    ticks_from_obt,
)

coarse_st = st.integers(0, MAX_COARSE)
fine_st = st.integers(0, 0xFFFF)
obt_st = st.floats(min_value=0.0, max_value=MAX_OBT_S, allow_nan=False, allow_infinity=False)


def test_p_field_is_level2_agency_epoch_four_coarse_two_fine() -> None:
    """The P-field bits read 0 (no extension), 010 (agency epoch), 11 (4 coarse), 10 (2 fine)."""
    assert P_FIELD == 0b0_010_11_10 == 0x2E
    assert CUC_LEN == 7
    assert TICK_S == 2.0**-16


def test_known_stamp_bytes() -> None:
    """A hand-computed stamp: 0x01020304 s + 0x8000 ticks = 16909060.5 s."""
    raw = bytes.fromhex("2E0102030480 00".replace(" ", ""))
    assert cuc_decode(raw) == 16909060.5
    assert cuc_encode(16909060.5) == raw


@given(coarse_st, fine_st)
def test_ticks_round_trip_exactly(coarse: int, fine: int) -> None:
    """Every (coarse, fine) pair encodes to 7 bytes and decodes to the same integers and the exact float."""
    raw = cuc_from_ticks(coarse, fine)
    assert len(raw) == CUC_LEN and raw[0] == P_FIELD
    assert ticks_from_cuc(raw) == (coarse, fine)
    t = cuc_decode(raw)
    assert Fraction(t) == coarse + Fraction(fine, 65536)
    assert t == obt_from_ticks(coarse, fine)
    assert cuc_encode(t) == raw
    assert ticks_from_obt(t) == (coarse, fine)


@given(obt_st)
def test_any_time_decodes_within_half_a_tick(obt_s: float) -> None:
    """decode(encode(t)) is the grid point nearest t: within half a tick (exact rational arithmetic)."""
    back = cuc_decode(cuc_encode(obt_s))
    assert abs(Fraction(back) - Fraction(obt_s)) <= Fraction(1, 2 * 65536)


@given(obt_st, obt_st)
def test_encoding_is_monotonic(a: float, b: float) -> None:
    """Later times never get earlier stamps: the big-endian bytes order as the times."""
    lo, hi = min(a, b), max(a, b)
    assert cuc_encode(lo) <= cuc_encode(hi)


@pytest.mark.parametrize("bad", [-TICK_S, -1.0, MAX_OBT_S + 1.0, math.inf, -math.inf, math.nan, 2.0**32])
def test_out_of_range_time_raises(bad: float) -> None:
    """Negative, too large and non-finite times raise CucRangeError naming obt_s."""
    with pytest.raises(CucRangeError, match="obt_s"):
        cuc_encode(bad)


@pytest.mark.parametrize(
    ("coarse", "fine", "field"),
    [(-1, 0, "coarse"), (MAX_COARSE + 1, 0, "coarse"), (0, -1, "fine"), (0, 65536, "fine")],
)
def test_out_of_range_ticks_raise(coarse: int, fine: int, field: str) -> None:
    """Ticks outside 4 coarse / 2 fine octets raise CucRangeError naming the field."""
    with pytest.raises(CucRangeError, match=field):
        cuc_from_ticks(coarse, fine)


def test_largest_time_is_representable() -> None:
    """The last tick before 2^32 s encodes to all-ones and back."""
    assert cuc_encode(MAX_OBT_S) == bytes([P_FIELD]) + b"\xff" * 6
    assert cuc_decode(b"\x2e" + b"\xff" * 6) == MAX_OBT_S


@pytest.mark.parametrize(
    ("raw", "why"),
    [
        (b"", "empty"),
        (b"\xae" + bytes(6), "extension"),
        (b"\x1e" + bytes(6), "time code id"),
        (b"\x2f" + bytes(7), "fine octets"),
        (b"\x2e" + bytes(5), "announces 7"),
        (b"\x2e" + bytes(7), "announces 7"),
    ],
)
def test_malformed_stamps_raise(raw: bytes, why: str) -> None:
    """Empty, extended, wrong-epoch, too-fine and wrong-length stamps raise CucFormatError with the reason."""
    with pytest.raises(CucFormatError, match=why):
        cuc_decode(raw)


@given(st.integers(0, 0xFFFFFF), st.integers(0, 0xFF))
def test_coarser_stamps_rescale_exactly(coarse: int, fine: int) -> None:
    """A 3-coarse, 1-fine stamp (P-field 0x29) decodes to coarse + fine/256 exactly."""
    raw = bytes([0b0_010_10_01]) + coarse.to_bytes(3, "big") + bytes([fine])
    assert Fraction(cuc_decode(raw)) == coarse + Fraction(fine, 256)
    assert ticks_from_cuc(raw) == (coarse, fine << 8)
