"""The deep-space link between ground and spacecraft: packets arrive one light time late, in order.

Each direction is a FIFO pipe: a packet starts being radiated when the previous one has been sent
(``size * 8 / rate`` seconds each) and arrives one light time after its last bit left. The universe owns the
link because only it knows true time; ground and OBSW see packets arrive, never the delay itself.
A link outage (a fault) drops what is radiated during it: the packets are counted as lost, not queued.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from contracts.link import LinkConfig


@dataclass
class Pipe:
    """One direction of the link."""

    light_time_s: float
    rate_bps: float
    in_flight: deque[tuple[float, bytes]] = field(default_factory=deque)
    free_at_s: float = float("-inf")
    sent: int = 0
    delivered: int = 0
    lost: int = 0

    def send(self, t_s: float, packets: list[bytes] | tuple[bytes, ...], outage: bool = False) -> None:
        """Radiate ``packets`` at true time ``t_s`` (queued behind what is still being sent)."""
        for p in packets:
            self.sent += 1
            start = max(t_s, self.free_at_s)
            self.free_at_s = start + len(p) * 8.0 / self.rate_bps
            if outage:
                self.lost += 1
                continue
            self.in_flight.append((self.free_at_s + self.light_time_s, p))

    def arrived(self, t_s: float) -> list[bytes]:
        """Packets whose last bit has arrived by true time ``t_s``, in the order sent."""
        if not self.in_flight or self.in_flight[0][0] > t_s:  # nothing due (most periods): no lists made
            return []
        return [p for _, p in self.arrived_timed(t_s)]

    def arrived_timed(self, t_s: float) -> list[tuple[float, bytes]]:
        """Like ``arrived``, with the true time at which each packet's last bit arrived."""
        out = []
        while self.in_flight and self.in_flight[0][0] <= t_s:
            out.append(self.in_flight.popleft())
        self.delivered += len(out)
        return out


class SpaceLink:
    """Uplink (telecommands) and downlink (telemetry) pipes with the configured light time and rates."""

    def __init__(self, cfg: LinkConfig) -> None:
        self.uplink = Pipe(cfg.one_way_light_time_s, cfg.uplink_rate_bps)
        self.downlink = Pipe(cfg.one_way_light_time_s, cfg.downlink_rate_bps)
