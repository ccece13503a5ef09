"""Parameters of the deep-space link, shared vocabulary of the universe (the true link) and the ground (its
knowledge of the link)."""

from __future__ import annotations

from pydantic import Field

from contracts.model import Config


class LinkConfig(Config):
    """Deep-space link between ground and spacecraft (about 33 s one way at 10 million km)."""

    one_way_light_time_s: float = Field(33.4, ge=0, description="one-way light time, s (10 million km / c)")
    downlink_rate_bps: float = Field(
        64000.0, gt=0, description="downlink data rate, bit/s (a CubeSat X-band link via DSN class)"
    )
    uplink_rate_bps: float = Field(2000.0, gt=0, description="uplink data rate, bit/s")
