"""The on-board trajectory candidates as the analysis rebuilds them: the nominal trajectory ground uploads and the
recognition grid the flight software builds around it."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from obsw.recognition import TrajectoryRecognizer
from obsw.trajectory import NominalTrajectory
from scenario import compose
from scenario.model import Scenario


def uploaded_nominal(scenario: Scenario) -> NominalTrajectory:
    """The nominal trajectory ground uploads at the start of the run (a-priori OBT-UTC correlation)."""
    # ground's belief alone: the bad-pixel calibration (a dark frame rendered and ranked) does not change the nominal
    tc = compose.ground_segment(scenario, calibrate=False).nominal_trajectory_tc()
    return NominalTrajectory(
        ca_time_obt_s=tc.ca_obt_s, ca_distance_km=tc.ca_distance_km, speed_km_s=tc.speed_km_s,
        approach_direction=tc.approach_direction, ca_direction=tc.ca_direction,
        ca_time_sigma_s=tc.sigma_ca_time_s, ca_distance_sigma_km=tc.sigma_ca_distance_km,
    )


def candidate_axes(scenario: Scenario) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The on-board candidate grid: C/A times (OBT s) and distances (km), as the OBSW builds it."""
    return TrajectoryRecognizer(uploaded_nominal(scenario), scenario.obsw.recognition).candidate_axes()
