"""The counters that stamp each telemetry packet: the packet sequence count of the APID, and the PUS-C message type
counter, one per message type (service, subtype) and destination (ECSS-E-ST-70-41C, TM secondary header)."""

from __future__ import annotations

from contracts import pus

MESSAGE_COUNTER_MODULO = 0x10000  # the message type counter is 16 bits


class TmCounters:
    """The next packet sequence count of one APID and the next message type counter of each (type, destination)."""

    def __init__(self) -> None:
        self._seq = 0
        self._per_type: dict[tuple[int, int, int], int] = {}

    def stamp(self, service: int, subtype: int, destination_id: int) -> tuple[int, int]:
        """(packet sequence count, message type counter) of the next packet of (service, subtype) to the destination."""
        seq = self._seq
        self._seq = (seq + 1) % pus.SEQ_COUNT_MODULO
        key = (service, subtype, destination_id)
        counter = self._per_type.get(key, 0)
        self._per_type[key] = (counter + 1) % MESSAGE_COUNTER_MODULO
        return seq, counter
