"""The composition of a run: the three cores built from a scenario, each from its own section only.

The flight software gets ``obsw`` (what is on board), the universe ``universe`` (the truth) and the seed, the
ground ``ground`` and what it believes of the flyby. The nodes and the in-process runner build their cores
here, so a node started alone on another host composes exactly what ``flyby run`` composes.
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from pydantic import ValidationError

from contracts import pus
from contracts.sdls import KeyRing
from contracts.seeding import rng_streams
from ground.config import FlybyBelief
from scenario.model import Scenario
from timeline.model import Timeline
from universe.config import CameraConfig
from universe.geometry import dimorphos_line, nominal_ca

if TYPE_CHECKING:
    from ground.segment import GroundSegment
    from obsw.software import FlightSoftware
    from universe.simulator import Universe

# Each core is imported where it is built: a node imports its own core only (the flight software alone takes about
# a second to import, and the three nodes start at once on the same cores).


def flight_software(scenario: Scenario, keys: KeyRing | None) -> FlightSoftware:
    """The on-board software, configured with on-board knowledge only, holding ``keys`` to authenticate TCs."""
    from obsw.software import FlightSoftware

    return FlightSoftware(scenario.obsw, keys)


def universe(scenario: Scenario) -> Universe:
    """The universe simulator: the truth of the run, seeded. OpenCV renders on one thread: on these frames its
    threads cost more processor time than they save wall time, and a campaign runs a run per core
    (``bench/speed.py``: the same frames, bit for bit)."""
    import cv2

    from universe.simulator import Universe

    cv2.setNumThreads(1)
    return Universe(scenario.universe, scenario.seed, apid=scenario.obsw.apid,
                    ground_period_s=scenario.ground.step_period_s)


def ground_belief(scenario: Scenario) -> FlybyBelief:
    """What ground believes of the flyby: the target's, Dimorphos's, true trajectory (``dimorphos_line``: ground's
    ephemeris of the binary is the truth's orbit) plus the knowledge error of its C/A time and distance drawn with
    the seed. The target's, not the barycentre's: the flight software tracks Dimorphos, and Dimorphos's place on its
    orbit across the flyby plane is a tilt of the plane that no C/A time or distance it recognises can take up."""
    u = scenario.universe
    line = dimorphos_line(u.flyby, u.bodies)
    unc = u.uncertainty
    ca_utc_s, ca_km = nominal_ca(line, unc, rng_streams(scenario.seed)["nominal"])
    return FlybyBelief(ca_utc_s=ca_utc_s, ca_distance_km=ca_km, speed_km_s=line.speed_km_s,
                       approach_direction=line.approach_direction, ca_direction=line.ca_direction,
                       ca_time_sigma_s=unc.ca_time_sigma_s, ca_distance_sigma_km=unc.ca_distance_sigma_km)


def ground_bad_pixel_map(scenario: Scenario) -> tuple[pus.LoadBadPixelMap, int]:
    """Ground's bad-pixel map of the camera from its calibration, and how many bad pixels the calibration found.

    The calibration takes the pixels of the run's dark frame (the universe's ``dark_frame`` at the planned exposure,
    drawn from the same seeded stream) more than ``bad_pixel_k_sigma`` robust sigmas above its median, the hot and
    warm pixels that matter at that exposure; and the sensor's dead pixels and columns, which read the bias in a dark
    frame and are known from flat fields (its fixed maps). The map is one telecommand: when the calibration finds
    more than fits in one packet, it keeps the dead pixels, then the brightest."""
    return _calibration(scenario.universe.camera, scenario.obsw.camera.exposure_s, scenario.seed,
                        scenario.ground.bad_pixel_k_sigma, scenario.ground.apid)


@lru_cache(maxsize=4)  # the cases of a dry run share one camera: its dark frame is rendered once
def _calibration(cam: CameraConfig, exposure_s: float, seed: int, k_sigma: float,
                 apid: int) -> tuple[pus.LoadBadPixelMap, int]:
    """``ground_bad_pixel_map`` of the values it depends on."""
    from universe.camera import dark_frame, sensor_defects

    dark = dark_frame(cam, exposure_s, rng_streams(seed)["dark_frame"]).reshape(-1)
    median = float(np.median(dark))
    sigma = 1.4826 * float(np.median(np.abs(dark - median)))
    bright = np.flatnonzero(dark > median + k_sigma * max(sigma, 0.5))
    defects = sensor_defects(cam)
    columns = {int(c) for c in defects.dead_columns}
    dead = np.unique(defects.dead_idx)
    bright = bright[~np.isin(bright, dead)]
    ranked = np.concatenate([dead, bright[np.argsort(-dark[bright], kind="stable")]]).astype(np.int64)
    ranked = ranked[~np.isin(ranked % cam.resolution_px, list(columns))]

    def load(n: int) -> pus.LoadBadPixelMap:
        idx = np.sort(ranked[:n])  # the map in pixel order, as before
        rows, cols = np.divmod(idx, cam.resolution_px)
        return pus.LoadBadPixelMap(columns=tuple(sorted(columns)), pixels=tuple(
            pus.BadPixel(col=int(c), row=int(r)) for c, r in zip(cols, rows, strict=True)))

    def fits(n: int) -> bool:
        try:
            pus.encode_tc(load(n), apid, 0)
        except (ValidationError, pus.PacketError):
            return False
        return True

    n = len(ranked)
    if not fits(n):  # the largest count that fits one packet, by bisection
        lo, hi = 0, n
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if fits(mid) else (lo, mid)
        n = lo
    return load(n), len(ranked)


def ground_segment(scenario: Scenario, timeline: Timeline | None = None, keys: KeyRing | None = None,
                   calibrate: bool = True) -> GroundSegment:
    """The ground segment with its belief of the flyby, the timeline it uploads, the keys it secures TCs with and
    its calibration of the camera's bad pixels (not made when not ``calibrate``: no bad-pixel map to upload, for
    whoever needs only the belief, as the analysis does; the calibration renders a dark frame)."""
    from ground.segment import GroundSegment

    bad, found = ground_bad_pixel_map(scenario) if calibrate and scenario.ground.upload_bad_pixel_map else (None, 0)
    return GroundSegment(scenario.ground, ground_belief(scenario), scenario.epoch_utc, timeline, keys,
                         bad_pixel_map=bad, bad_pixels_found=found)
