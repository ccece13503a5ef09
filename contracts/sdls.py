"""Telecommand authentication in the manner of CCSDS 355.0-B (Space Data Link Security, authentication mode).

Every radiated telecommand travels in a secured unit: a security header, the complete TC space packet, and a
security trailer::

    | SPI u16 | ARSN u32 | TC space packet (with its CRC) | MAC, 16 octets |

The security parameter index (SPI) names the security association (SA) whose key authenticates the unit; the
anti-replay sequence number (ARSN) grows by one per unit sent under that SA, and the receiver accepts a unit only if
its ARSN is above the last one it accepted; the MAC is HMAC-SHA-256 over the security header and the packet,
truncated to its first 16 octets (CCSDS 355.0-B lets an SA choose the MAC length). TCs carried inside a schedule
insert are plain packets: the insert that carries them was authenticated when it was received.

Keys live in a key file (JSON, mode 0600) that is never part of the scenario, the logs or the run folder. A new
key can be loaded by telecommand (``RekeySecurityAssociation``): wrapped (AES key wrap, RFC 3394) under a key derived
from the association that authenticates the TC; the receiver then accepts both until the first unit under the new
association, and retires the old one, so a lost rekeying TC never locks the ground out.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import stat
import struct
from dataclasses import dataclass
from pathlib import Path

from cryptography.hazmat.primitives.keywrap import InvalidUnwrap, aes_key_unwrap, aes_key_wrap

from contracts.errors import FlybyError
from contracts.packet_errors import MAX_APID, MAX_SEQ_COUNT, FailureCode, RequestId
from contracts.wire import PRIMARY_HEADER_LEN, packet_len

SECURITY_HEADER = struct.Struct(">HI")
SECURITY_HEADER_LEN = SECURITY_HEADER.size  # 6 octets: SPI, ARSN
MAC_LEN = 16
KEY_LEN = 32  # HMAC-SHA-256 keys of the hash's own block-safe size, 256 bits
MAX_ARSN = 0xFFFFFFFF
ALGORITHM = "HMAC-SHA-256"
KEY_WRAP_LABEL = b"flyby SDLS key wrap"
KEY_FILE_FORMAT = "flyby-sdls-keys/1"


class KeyFileError(FlybyError):
    """A key file that cannot be used; the message names the file and what is wrong."""


class SecurityRejection(FlybyError):
    """A secured unit that fails the check: ``failure_code`` is its service 1 code; ``spi``, ``arsn`` and
    ``request_id`` are what could be read (0, 0 and None when the unit is too short)."""

    def __init__(self, failure_code: FailureCode, why: str, spi: int = 0, arsn: int = 0,
                 request_id: RequestId | None = None) -> None:
        self.failure_code = failure_code
        self.why = why
        self.spi = spi
        self.arsn = arsn
        self.request_id = request_id
        super().__init__(why)


@dataclass(frozen=True)
class SecurityAssociation:
    """One security association: its SPI and key."""

    spi: int
    key: bytes

    def mac(self, authenticated: bytes) -> bytes:
        """The truncated HMAC-SHA-256 of ``authenticated``."""
        return hmac.new(self.key, authenticated, hashlib.sha256).digest()[:MAC_LEN]

    def _wrapping_key(self) -> bytes:
        # a key of its own for wrapping, derived from the association's: one key never serves two algorithms
        return hmac.new(self.key, KEY_WRAP_LABEL, hashlib.sha256).digest()

    def wrap(self, new_key: bytes) -> bytes:
        """``new_key`` wrapped (AES key wrap, RFC 3394) for a rekeying TC sent under this association."""
        return aes_key_wrap(self._wrapping_key(), new_key)

    def unwrap(self, wrapped: bytes) -> bytes:
        """The key ``wrap`` wrapped; ValueError if it was not wrapped under this association."""
        try:
            key = aes_key_unwrap(self._wrapping_key(), wrapped)
        except InvalidUnwrap:
            raise ValueError(f"the new key was not wrapped under SPI {self.spi}") from None
        if len(key) != KEY_LEN:
            raise ValueError(f"the new key has {len(key)} octets, {KEY_LEN} are needed")
        return key


@dataclass(frozen=True)
class KeyRing:
    """The security associations both ends hold, and the one ground sends under."""

    associations: tuple[SecurityAssociation, ...]
    active_spi: int

    def __post_init__(self) -> None:
        spis = [sa.spi for sa in self.associations]
        if len(set(spis)) != len(spis):
            raise KeyFileError(f"two security associations share an SPI: {sorted(spis)}")
        if self.active_spi not in spis:
            raise KeyFileError(f"active_spi {self.active_spi} names no security association (have {sorted(spis)})")

    def get(self, spi: int) -> SecurityAssociation | None:
        """The association of ``spi``, or None."""
        return next((sa for sa in self.associations if sa.spi == spi), None)

    @classmethod
    def generate(cls, spis: tuple[int, ...] = (1, 2)) -> KeyRing:
        """Fresh random keys for ``spis``, the first one active (the others are spares to switch to)."""
        return cls(tuple(SecurityAssociation(spi, secrets.token_bytes(KEY_LEN)) for spi in spis), spis[0])

    @classmethod
    def derived(cls, seed: int, spis: tuple[int, ...] = (1, 2)) -> KeyRing:
        """Keys fixed by ``seed``, for runs that must reproduce their uplink byte for byte (in-process runs and
        campaigns, where nobody else is on the link): not secret, never for a run on a bus others can reach."""
        digest = hashlib.sha256(f"flyby in-process keys, seed {seed}".encode())
        keys = []
        for spi in spis:
            digest.update(spi.to_bytes(2, "big"))
            keys.append(SecurityAssociation(spi, digest.digest()[:KEY_LEN]))
        return cls(tuple(keys), spis[0])

    def to_json(self) -> str:
        """The key file's text."""
        return json.dumps({"format": KEY_FILE_FORMAT, "algorithm": ALGORITHM, "active_spi": self.active_spi,
                           "associations": [{"spi": sa.spi, "key": sa.key.hex()} for sa in self.associations]},
                          indent=2)


def write_key_file(path: Path, keys: KeyRing) -> None:
    """Write ``keys`` to a new file readable by its owner only (0600); an existing file is refused."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(keys.to_json())


def load_key_file(path: Path) -> KeyRing:
    """Read a key file written by ``write_key_file``; KeyFileError naming the file and the problem."""
    try:
        mode = path.stat().st_mode
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise KeyFileError(f"{path}: cannot read the key file: {exc.strerror}") from None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise KeyFileError(f"{path}: the key file is readable by others (mode {stat.S_IMODE(mode):04o}); "
                           "chmod 600 it")
    try:
        data = json.loads(text)
        if data.get("format") != KEY_FILE_FORMAT or data.get("algorithm") != ALGORITHM:
            raise ValueError(f"format must be {KEY_FILE_FORMAT!r} with algorithm {ALGORITHM!r}")
        sas = []
        for i, entry in enumerate(data["associations"]):
            spi, key = int(entry["spi"]), bytes.fromhex(entry["key"])
            if not 1 <= spi <= 0xFFFF:
                raise ValueError(f"associations[{i}].spi {spi} is outside 1..65535")
            if len(key) != KEY_LEN:
                raise ValueError(f"associations[{i}].key has {len(key)} octets, {KEY_LEN} are needed")
            sas.append(SecurityAssociation(spi, key))
        return KeyRing(tuple(sas), int(data["active_spi"]))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise KeyFileError(f"{path}: not a key file: {exc}") from None


def secure(packet: bytes, sa: SecurityAssociation, arsn: int) -> bytes:
    """The secured unit of a TC ``packet``, sent under ``sa`` with anti-replay number ``arsn``."""
    if not 0 <= arsn <= MAX_ARSN:
        raise ValueError(f"arsn {arsn} is outside 0..{MAX_ARSN}")
    authenticated = SECURITY_HEADER.pack(sa.spi, arsn) + bytes(packet)
    return authenticated + sa.mac(authenticated)


def packet_of(unit: bytes) -> bytes:
    """The TC packet inside a secured unit (no check: for the ground's own record of what it radiated)."""
    return bytes(unit[SECURITY_HEADER_LEN:-MAC_LEN])


def _request_id(packet: bytes) -> RequestId | None:
    """The request id of what looks like a TC packet, or None."""
    if len(packet) < 4:
        return None
    w0, w1 = struct.unpack_from(">HH", packet)
    return RequestId(apid=w0 & MAX_APID, seq_count=w1 & MAX_SEQ_COUNT)


def _plain_tc(unit: bytes) -> bool:
    """Whether ``unit`` is itself a whole TC space packet (sent without the security envelope)."""
    return len(unit) >= PRIMARY_HEADER_LEN and bool(unit[0] & 0x10) and packet_len(unit) == len(unit)


class Sender:
    """Ground's end: secures each TC under the active SA with the next anti-replay number."""

    def __init__(self, keys: KeyRing) -> None:
        self.keys = keys
        active = keys.get(keys.active_spi)
        assert active is not None
        self.active = active
        self._arsn: dict[int, int] = {}

    def secure(self, packet: bytes) -> bytes:
        """The secured unit of ``packet``."""
        arsn = self._arsn.get(self.active.spi, 0) + 1
        self._arsn[self.active.spi] = arsn
        return secure(packet, self.active, arsn)

    def new_association(self, spi: int) -> tuple[SecurityAssociation, bytes]:
        """A fresh association ``spi`` and its key wrapped under the active one (for a rekeying TC); the sender
        keeps the active one until ``switch``."""
        sa = SecurityAssociation(spi, secrets.token_bytes(KEY_LEN))
        return sa, self.active.wrap(sa.key)

    def switch(self, sa: SecurityAssociation) -> None:
        """Send under ``sa`` from now on (once the spacecraft has confirmed it holds it)."""
        self.active = sa


class Receiver:
    """The spacecraft's end: checks each secured unit and keeps the last accepted ARSN of each SA."""

    def __init__(self, keys: KeyRing | None) -> None:
        self.associations = {} if keys is None else {sa.spi: sa for sa in keys.associations}
        self.last_arsn: dict[int, int] = {}
        self.last_spi: int | None = None  # the association of the last unit accepted
        self._retire: dict[int, int] = {}  # new SPI -> the SPI it replaces, retired at the new one's first use

    def install(self, spi: int, wrapped: bytes) -> None:
        """Add association ``spi`` with the key ``wrapped`` under the association of the last accepted unit; that
        one is retired once a unit under ``spi`` is accepted. ValueError if ``spi`` is taken or the key does not
        unwrap."""
        if self.last_spi is None:
            raise ValueError("no authenticated unit to take the wrapping key from")
        if spi in self.associations:
            raise ValueError(f"SPI {spi} already names a security association")
        self.associations[spi] = SecurityAssociation(spi, self.associations[self.last_spi].unwrap(wrapped))
        self._retire[spi] = self.last_spi

    def check(self, unit: bytes) -> bytes:
        """The TC packet of an authentic, fresh ``unit``; SecurityRejection otherwise.

        The MAC is checked before the ARSN, so a forged unit can never move the anti-replay window.
        """
        unit = bytes(unit)
        if len(unit) < SECURITY_HEADER_LEN + MAC_LEN:
            raise SecurityRejection(FailureCode.UNAUTHENTICATED,
                                    f"{len(unit)} octets cannot hold the security header and MAC "
                                    f"({SECURITY_HEADER_LEN + MAC_LEN})", request_id=_request_id(unit))
        spi, arsn = SECURITY_HEADER.unpack_from(unit)
        packet = packet_of(unit)
        rid = _request_id(packet)
        sa = self.associations.get(spi)
        if sa is None and _plain_tc(unit):
            raise SecurityRejection(FailureCode.UNAUTHENTICATED, "a TC packet without security header and MAC",
                                    request_id=_request_id(unit))
        if sa is None:
            raise SecurityRejection(FailureCode.UNKNOWN_SPI, f"no security association has SPI {spi}", spi, arsn, rid)
        if not hmac.compare_digest(sa.mac(unit[:-MAC_LEN]), unit[-MAC_LEN:]):
            raise SecurityRejection(FailureCode.UNAUTHENTICATED, f"MAC does not verify under SPI {spi}", spi, arsn,
                                    rid)
        last = self.last_arsn.get(spi, 0)
        if arsn <= last:
            raise SecurityRejection(FailureCode.REPLAYED, f"ARSN {arsn} is not above the last accepted {last} "
                                    f"(SPI {spi})", spi, arsn, rid)
        self.last_arsn[spi] = arsn
        self.last_spi = spi
        retired = self._retire.pop(spi, None)
        if retired is not None:
            self.associations.pop(retired, None)
        return packet
