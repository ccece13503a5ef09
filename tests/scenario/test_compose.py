"""Composition of the cores from a scenario: ground's calibration of the camera and its belief of the flyby."""

from __future__ import annotations

import numpy as np

from contracts import pus
from contracts.seeding import rng_streams
from scenario import compose
from scenario.model import scenario_from_dict
from universe.camera import dark_frame, sensor_defects
from universe.geometry import FlybyGeometry


def _scenario(**camera: float):  # noqa: ANN202
    """A default scenario with these camera fields."""
    return scenario_from_dict({"name": "calibration", "universe": {"camera": camera}})


def test_the_map_lists_the_dead_pixels_and_the_dark_frame_outliers_outside_the_dead_columns() -> None:
    """Every pixel of the map is a dead pixel or reads above the threshold in the run's dark frame; none lies in a
    dead column, and every dead pixel outside the dead columns is in it."""
    sc = _scenario()
    m, found = compose.ground_bad_pixel_map(sc)
    cam = sc.universe.camera
    dark = dark_frame(cam, sc.obsw.camera.exposure_s, rng_streams(sc.seed)["dark_frame"])
    defects = sensor_defects(cam)
    median = float(np.median(dark))
    sigma = 1.4826 * float(np.median(np.abs(dark - median)))
    threshold = median + sc.ground.bad_pixel_k_sigma * max(sigma, 0.5)
    dead = {(int(i) % cam.resolution_px, int(i) // cam.resolution_px) for i in defects.dead_idx}
    listed = {(p.col, p.row) for p in m.pixels}
    assert found == len(m.pixels) > 0
    assert all(c not in m.columns for c, _ in listed)
    assert all((c, r) in dead or dark[r, c] > threshold for c, r in listed)
    assert {(c, r) for c, r in dead if c not in m.columns} <= listed


def test_a_calibration_finding_more_than_one_packet_holds_keeps_the_dead_then_the_brightest() -> None:
    """A dark frame clipped at zero (no bias) makes most pixels outliers: the map still fits one TC, holds every
    dead pixel and, of the others, only pixels at least as bright as any it leaves out."""
    sc = _scenario(dark_offset_dn=0.0)
    m, found = compose.ground_bad_pixel_map(sc)
    assert found > len(m.pixels) > 1000
    pus.encode_tc(m, sc.ground.apid, 0)  # fits one packet
    cam = sc.universe.camera
    dark = dark_frame(cam, sc.obsw.camera.exposure_s, rng_streams(sc.seed)["dark_frame"])
    defects = sensor_defects(cam)
    dead = {int(i) for i in defects.dead_idx if int(i) % cam.resolution_px not in m.columns}
    listed = {p.row * cam.resolution_px + p.col for p in m.pixels}
    assert dead <= listed
    kept = dark.reshape(-1)[sorted(listed - dead)]
    left = np.ones(dark.size, dtype=bool)
    left[sorted(listed)] = False
    assert kept.min() >= dark.reshape(-1)[left].max()


def test_ground_believes_the_line_of_sight_to_dimorphos_whatever_the_flyby_plane() -> None:
    """Without a knowledge error, the trajectory ground uploads points along the true line of sight to Dimorphos
    (within 2e-6 rad over the whole run) for flyby planes along, across and slanted to Dimorphos's orbit, and at
    every orbital phase: ground's trajectory is the target's, not the barycentre's (up to 21 mrad apart at C/A)."""
    for ca_direction in ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.5), (0.3, 0.2, -1.0)):
        for phase_deg in (0.0, 90.0, 135.0, 250.0):
            sc = scenario_from_dict({"name": "belief", "universe": {
                "flyby": {"ca_direction": list(ca_direction)}, "bodies": {"orbit_phase_deg": phase_deg},
                "uncertainty": {"ca_time_sigma_s": 0.0, "ca_distance_sigma_km": 0.0}}})
            b = compose.ground_belief(sc)
            t = np.linspace(sc.universe.start_s, sc.universe.end_s, 2001)
            believed = (b.ca_distance_km * 1e3 * np.asarray(b.ca_direction)
                        + (b.speed_km_s * 1e3 * (t - b.ca_utc_s))[:, None] * np.asarray(b.approach_direction))
            g = FlybyGeometry(sc.universe.flyby, sc.universe.bodies)
            true = g.dimorphos_position_m(t) - g.spacecraft_position_m(t)
            cos = np.sum(-believed * true, axis=1) / np.linalg.norm(believed, axis=1) / np.linalg.norm(true, axis=1)
            worst = float(np.max(np.arccos(np.clip(cos, -1.0, 1.0))))
            assert worst < 2e-6, (ca_direction, phase_deg, worst)
