"""The on-board end of telecommand authentication (``contracts.sdls``): every uplinked unit is checked before its
TC is decoded, and the rejections are counted by kind for housekeeping."""

from __future__ import annotations

from contracts import pus, sdls

COUNTER_MAX = 0xFFFF  # the housekeeping counters are u16 and saturate


class TcSecurity:
    """Checks uplinked units against the on-board security associations (none: every unit is refused)."""

    def __init__(self, keys: sdls.KeyRing | None) -> None:
        self._receiver = sdls.Receiver(keys)
        self.keep_verdicts = False  # a recorder sets it, then takes each period's outcomes
        self.verdicts: list[bytes | sdls.SecurityRejection] = []
        self.rejected = {code: 0 for code in (pus.FailureCode.UNAUTHENTICATED, pus.FailureCode.UNKNOWN_SPI,
                                              pus.FailureCode.REPLAYED)}

    def check(self, unit: bytes) -> bytes:
        """The TC packet of an authentic, fresh unit; ``sdls.SecurityRejection`` (counted) otherwise."""
        try:
            packet = self._receiver.check(unit)
        except sdls.SecurityRejection as rej:
            self.rejected[rej.failure_code] = min(self.rejected[rej.failure_code] + 1, COUNTER_MAX)
            if self.keep_verdicts:
                self.verdicts.append(rej)
            raise
        if self.keep_verdicts:
            self.verdicts.append(packet)
        return packet

    def take_verdicts(self) -> list[bytes | sdls.SecurityRejection]:
        """The outcomes of the checks since the last call, in order: the TC packet passed, or the rejection."""
        out, self.verdicts = self.verdicts, []
        return out

    def install(self, spi: int, wrapped_key: bytes) -> None:
        """Load association ``spi`` from a rekeying TC, its key wrapped under the association that authenticated it;
        ValueError naming what is wrong."""
        self._receiver.install(spi, wrapped_key)

    def housekeeping(self) -> dict[str, int]:
        """The rejection counters, as the housekeeping report's fields."""
        r = self.rejected
        return {"tc_rejected_auth": r[pus.FailureCode.UNAUTHENTICATED],
                "tc_rejected_spi": r[pus.FailureCode.UNKNOWN_SPI],
                "tc_rejected_replay": r[pus.FailureCode.REPLAYED]}
