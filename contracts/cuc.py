"""CCSDS Unsegmented time Code (CUC, CCSDS 301.0-B-4 section 3.2) for on-board time (OBT).

spacepackets 0.32 only provides CDS, so the CUC is written here. The mission's choice:

- P-field: one octet, no extension, time code identification ``010`` (level 2: agency-defined epoch, which is
  the OBT epoch of the on-board clock), 4 coarse octets (seconds) and 2 fine octets (2^-16 s).
  Binary ``0 010 11 10`` = ``0x2E``.
- T-field: coarse seconds (32 bit) then fine ticks (16 bit), both big-endian.

So a stamp is 7 octets (the size of a CDS short stamp, so PUS TM headers keep their usual length), the range is
0 to 2^32 - 2^-16 s (136 years) and the resolution is 2^-16 s = 15.3 us: 10 cm along track at 7 km/s, far below the
ms-level time knowledge the flyby needs. Encoding rounds to the nearest tick, so decode(encode(t)) is within half
a tick of t, and times on the tick grid (every float k * 2^-16) round-trip exactly.

Decoding honours any level-2 P-field with 1 to 4 coarse and 0 to 2 fine octets (rescaled exactly onto 2^-16 s),
so coarser stamps of other units parse too.
"""

from __future__ import annotations

import math
import struct

from contracts.errors import FlybyError

COARSE_OCTETS = 4
FINE_OCTETS = 2
FINE_TICKS_PER_S = 1 << (8 * FINE_OCTETS)
TICK_S = 1.0 / FINE_TICKS_PER_S
P_FIELD = (0b010 << 4) | ((COARSE_OCTETS - 1) << 2) | FINE_OCTETS
CUC_LEN = 1 + COARSE_OCTETS + FINE_OCTETS
MAX_COARSE = (1 << (8 * COARSE_OCTETS)) - 1
MAX_OBT_S = MAX_COARSE + (FINE_TICKS_PER_S - 1) * TICK_S

_AGENCY_EPOCH_ID = 0b010
# the mission's stamp (P-field, coarse and fine octets) as one struct, its formats from the octet counts above
_STAMP = struct.Struct(">B" + {1: "B", 2: "H", 4: "I"}[COARSE_OCTETS] + {1: "B", 2: "H"}[FINE_OCTETS])


class CucError(FlybyError, ValueError):
    """Base of CUC errors."""


class CucRangeError(CucError):
    """A time or tick count that the mission's CUC cannot represent."""


class CucFormatError(CucError):
    """Bytes that are not a CUC stamp this decoder understands (P-field, length)."""


def ticks_from_obt(obt_s: float) -> tuple[int, int]:
    """Return (coarse seconds, fine ticks of 2^-16 s) of the tick nearest to ``obt_s``."""
    if not isinstance(obt_s, (int, float)) or isinstance(obt_s, bool):
        raise CucRangeError(f"obt_s must be a real number, got {type(obt_s).__name__}")
    if not math.isfinite(obt_s) or obt_s < 0.0 or obt_s > MAX_OBT_S:
        raise CucRangeError(f"obt_s={obt_s!r} is outside the CUC range [0, {MAX_OBT_S!r}] s")
    # Multiplying a float by a power of two is exact, so the rounding below is the only approximation.
    total = round(float(obt_s) * FINE_TICKS_PER_S)
    return total >> (8 * FINE_OCTETS), total & (FINE_TICKS_PER_S - 1)


def obt_from_ticks(coarse: int, fine: int) -> float:
    """Return the OBT in seconds of (coarse seconds, fine ticks of 2^-16 s); exact in a float64."""
    _check_ticks(coarse, fine)
    return coarse + fine * TICK_S


def cuc_from_ticks(coarse: int, fine: int) -> bytes:
    """Return the 7-octet CUC (P-field + T-field) of exact integer (coarse, fine) ticks."""
    _check_ticks(coarse, fine)
    return _STAMP.pack(P_FIELD, coarse, fine)


def cuc_encode(obt_s: float) -> bytes:
    """Return the 7-octet CUC of the tick nearest to ``obt_s`` seconds of OBT."""
    return cuc_from_ticks(*ticks_from_obt(obt_s))


def ticks_from_cuc(data: bytes | bytearray | memoryview) -> tuple[int, int]:
    """Return (coarse seconds, fine ticks of 2^-16 s) of a CUC stamp; 0 or 1 fine octets are rescaled exactly."""
    if len(data) == CUC_LEN and data[0] == P_FIELD:  # the mission's own stamp (every one on board): one struct
        _, coarse, fine = _STAMP.unpack_from(data)
        return coarse, fine
    raw = bytes(data)
    if not raw:
        raise CucFormatError("CUC stamp is empty (no P-field)")
    p = raw[0]
    if p & 0x80:
        raise CucFormatError(f"CUC P-field 0x{p:02X} has the extension flag set; extended P-fields are not supported")
    epoch = (p >> 4) & 0b111
    if epoch != _AGENCY_EPOCH_ID:
        raise CucFormatError(
            f"CUC P-field 0x{p:02X} has time code id {epoch:03b}; "
            f"OBT uses the agency-defined epoch ({_AGENCY_EPOCH_ID:03b})"
        )
    n_coarse = ((p >> 2) & 0b11) + 1
    n_fine = p & 0b11
    if n_fine > FINE_OCTETS:
        # A finer stamp would have to be rounded onto our grid; no unit of this mission produces one.
        raise CucFormatError(f"CUC P-field 0x{p:02X} has {n_fine} fine octets; at most {FINE_OCTETS} are supported")
    expected = 1 + n_coarse + n_fine
    if len(raw) != expected:
        raise CucFormatError(f"CUC P-field 0x{p:02X} announces {expected} octets but {len(raw)} were given")
    coarse = int.from_bytes(raw[1 : 1 + n_coarse], "big")
    fine_raw = int.from_bytes(raw[1 + n_coarse :], "big")
    return coarse, fine_raw << (8 * (FINE_OCTETS - n_fine))


def cuc_decode(data: bytes | bytearray | memoryview) -> float:
    """Return the OBT in seconds of a CUC stamp (P-field + T-field)."""
    coarse, fine = ticks_from_cuc(data)
    return coarse + fine * TICK_S


def _check_ticks(coarse: int, fine: int) -> None:
    """Raise CucRangeError unless (coarse, fine) fit the mission's 4 + 2 octets."""
    for name, value, top in (("coarse", coarse, MAX_COARSE), ("fine", fine, FINE_TICKS_PER_S - 1)):
        if not isinstance(value, int) or isinstance(value, bool):
            raise CucRangeError(f"{name} must be an int, got {type(value).__name__}")
        if not 0 <= value <= top:
            raise CucRangeError(f"{name}={value} is outside [0, {top}]")
