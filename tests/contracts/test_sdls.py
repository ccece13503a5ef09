"""Telecommand authentication (contracts/sdls.py): the MAC is HMAC-SHA-256 truncated to 128 bits, any change to a
secured unit is refused, an old or repeated anti-replay number is refused, and key files are private."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from contracts import pus, sdls

KEYS = sdls.KeyRing.generate()
PACKET = pus.encode_tc(pus.SetMode(mode=pus.Mode.SAFE), 0x0C1, 5)


def test_mac_is_truncated_hmac_sha256() -> None:
    """RFC 4231 test case 5 (HMAC-SHA-256 truncated to 128 bits) gives the published value."""
    sa = sdls.SecurityAssociation(1, bytes([0x0C]) * 20)
    assert sa.mac(b"Test With Truncation").hex() == "a3b6167473100ee06e0c796c2955552b"


def test_secured_unit_layout() -> None:
    """SPI (u16) and ARSN (u32) ahead of the packet, 16 octets of MAC after it; the receiver returns the packet."""
    unit = sdls.Sender(KEYS).secure(PACKET)
    assert unit[:6] == bytes([0, KEYS.active_spi, 0, 0, 0, 1]) and unit[6:-16] == PACKET and len(unit[-16:]) == 16
    assert sdls.Receiver(KEYS).check(unit) == PACKET


@given(st.data())
def test_any_flipped_bit_is_refused(data: st.DataObject) -> None:
    """Flipping any one bit of a secured unit makes it refused, and the refusal does not move the ARSN window."""
    unit = bytearray(sdls.secure(PACKET, KEYS.associations[0], 7))
    bit = data.draw(st.integers(0, len(unit) * 8 - 1))
    unit[bit // 8] ^= 1 << (bit % 8)
    rx = sdls.Receiver(KEYS)
    with pytest.raises(sdls.SecurityRejection) as exc:
        rx.check(bytes(unit))
    assert exc.value.failure_code in (pus.FailureCode.UNAUTHENTICATED, pus.FailureCode.UNKNOWN_SPI)
    assert rx.last_arsn == {}


def test_replayed_and_old_units_are_refused() -> None:
    """A unit accepted once is refused the second time, and so is any older one; a newer one passes."""
    tx, rx = sdls.Sender(KEYS), sdls.Receiver(KEYS)
    first, second, third = (tx.secure(PACKET) for _ in range(3))
    rx.check(second)
    for old in (second, first):
        with pytest.raises(sdls.SecurityRejection) as exc:
            rx.check(old)
        assert exc.value.failure_code == pus.FailureCode.REPLAYED and exc.value.arsn in (1, 2)
        assert exc.value.request_id == pus.RequestId(apid=0x0C1, seq_count=5)
    assert rx.check(third) == PACKET


def test_plain_unknown_spi_short_and_foreign_key_units() -> None:
    """A bare TC is unauthenticated (its request id read), an unknown SPI is named, a stump is refused, and a unit
    under another key with a known SPI fails its MAC."""
    rx = sdls.Receiver(KEYS)
    cases = [(PACKET, pus.FailureCode.UNAUTHENTICATED),
             (sdls.secure(PACKET, sdls.SecurityAssociation(99, bytes(32)), 1), pus.FailureCode.UNKNOWN_SPI),
             (b"\x00\x01\x02", pus.FailureCode.UNAUTHENTICATED),
             (sdls.secure(PACKET, sdls.SecurityAssociation(KEYS.active_spi, bytes(32)), 1),
              pus.FailureCode.UNAUTHENTICATED)]
    for unit, code in cases:
        with pytest.raises(sdls.SecurityRejection) as exc:
            rx.check(unit)
        assert exc.value.failure_code == code, unit
    with pytest.raises(sdls.SecurityRejection) as exc:
        rx.check(PACKET)
    assert exc.value.request_id == pus.RequestId(apid=0x0C1, seq_count=5)
    with pytest.raises(sdls.SecurityRejection):
        sdls.Receiver(None).check(sdls.Sender(KEYS).secure(PACKET))


def test_key_file_round_trip_and_privacy(tmp_path: Path) -> None:
    """A key file is written 0600, read back equal, refused once others can read it, and refused when malformed."""
    path = tmp_path / "keys.json"
    sdls.write_key_file(path, KEYS)
    assert os.stat(path).st_mode & 0o777 == 0o600
    assert sdls.load_key_file(path) == KEYS
    with pytest.raises(FileExistsError):
        sdls.write_key_file(path, KEYS)
    path.chmod(0o644)
    with pytest.raises(sdls.KeyFileError, match="readable by others"):
        sdls.load_key_file(path)
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "flyby-sdls-keys/1", "algorithm": "HMAC-SHA-256", "active_spi": 1, '
                   '"associations": [{"spi": 1, "key": "00"}]}')
    bad.chmod(0o600)
    with pytest.raises(sdls.KeyFileError, match=r"associations\[0\].key has 1 octets"):
        sdls.load_key_file(bad)
    with pytest.raises(sdls.KeyFileError, match="cannot read"):
        sdls.load_key_file(tmp_path / "none.json")
