"""Configuration of the on-board software: rates, gains and mode thresholds, all in on-board time."""

from __future__ import annotations

from pydantic import Field

from flyby.model import Frozen


class ControlConfig(Frozen):
    """PD attitude control on quaternion error and body rate (paper: PD baseline, no integral term)."""

    kp_nm_per_rad: float = Field(0.012, gt=0, description="proportional gain, N m per rad of attitude error")
    kd_nms_per_rad: float = Field(0.09, gt=0, description="derivative gain, N m per rad/s of rate error")
    feedforward: bool = Field(True, description="add the reference angular acceleration times inertia")


class ModesConfig(Frozen):
    """Mode manager thresholds (paper: acquisition from C/A-240 s, autonomous from C/A-30 s)."""

    acquisition_before_ca_s: float = Field(240.0, gt=0, description="enter ACQUISITION this long before C/A, s")
    autonomous_before_ca_s: float = Field(30.0, gt=0, description="enter AUTONOMOUS_TRACKING this long before C/A, s")
    standby_after_ca_s: float = Field(90.0, gt=0, description="return to STANDBY this long after C/A, s")
    target_lost_timeout_s: float = Field(10.0, gt=0, description="declare the target lost after this long unseen, s")


class ObswConfig(Frozen):
    """Everything the on-board software is configured with before the flyby."""

    housekeeping_period_s: float = Field(1.0, gt=0, description="PUS service 3 housekeeping period, OBT s")
    apid: int = Field(0x0C1, ge=0, lt=2048, description="APID of the on-board software's packets")
    inertia_kgm2: tuple[tuple[float, float, float], ...] = Field(
        ((0.152, 0.0, 0.0), (0.0, 0.117, 0.0), (0.0, 0.0, 0.058)),
        description="on-board knowledge of the inertia matrix, kg m^2",
    )
    control: ControlConfig = ControlConfig()
    modes: ModesConfig = ModesConfig()
