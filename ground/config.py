"""Configuration of the ground segment and of the space link it talks through."""

from __future__ import annotations

from pydantic import Field

from flyby.model import Frozen


class LinkConfig(Frozen):
    """Deep-space link between ground and spacecraft (DESIGN: ~33 s one way at 10 million km)."""

    one_way_light_time_s: float = Field(33.4, ge=0, description="one-way light time, s")
    downlink_rate_bps: float = Field(
        64000.0, gt=0, description="downlink data rate, bit/s (a CubeSat X-band link via DSN class)"
    )
    uplink_rate_bps: float = Field(2000.0, gt=0, description="uplink data rate, bit/s")


class GroundConfig(Frozen):
    """What the ground segment does during a run."""

    step_period_s: float = Field(1.0, gt=0, description="how often ground exchanges with the link, s of UTC")
    apid: int = Field(0x0C1, ge=0, lt=2048, description="APID the ground addresses its telecommands to")
    upload_nominal_at_s: float | None = Field(
        None,
        description="true time at which ground uploads the nominal trajectory, s after the epoch "
        "(default: at the start of the run)",
    )
    link: LinkConfig = LinkConfig()
    timeline_file: str | None = Field(
        None, description="command timeline (YAML or CSV) uploaded after the nominal trajectory; a relative path is "
        "taken from the scenario file's folder"
    )
    upload_margin_s: float = Field(
        5.0, ge=0, description="ground refuses timeline commands tagged earlier than now + light time + this, s"
    )
    a_priori_obt_offset_s: float = Field(
        26_499_202.0,
        description="OBT minus UTC (s from the epoch) that ground assumes before any time report, s "
        "(default: the oscillator's default, a clock counting from launch)",
    )
    time_report_rate_exponent: int = Field(
        2, ge=0, le=16, description="ask for a service 9 time report every 2^n OBT s (PUS 9,1)"
    )
    correlation_window: int = Field(
        200, ge=3, description="number of most recent time reports the OBT-UTC fit uses"
    )
