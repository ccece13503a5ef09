"""Centroid-level fidelity: the modelled imaging-chain report against the pinhole truth and the model's own rates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from contracts.messages import FrameRequest, StepReply
from scenario import compose
from scenario.model import Scenario
from tests.numerics import assert_within_ulps
from universe.camera import Body, Scene, focal_length_px, project_camera, project_inertial
from universe.config import CameraConfig, CentroidModelConfig, UniverseConfig
from universe.measurement import MeasurementState, body_view, centroid_measurement, episode_frames, interp

CAMERA = CameraConfig()
PERFECT = dict(phase_deg=(0.0,), bias_radius_fraction=(0.0,), dimorphos_dropout=(0.0,), noise_px=0.0,
               noise_radius_fraction=0.0, merge_gap_px=(0.0,), merge_probability=(0.0,), didymos_dropout=0.0,
               misidentification=0.0, misidentification_frames=1.0)
F_1024 = 512.0 / math.tan(math.radians(2.9) / 2.0)  # closed-form focal length of the default camera, px
C_1024 = 511.5


def scene(dimorphos_offset_m: tuple[float, float] = (3000.0, 1000.0), range_m: float = 600_000.0,
          sun: tuple[float, float, float] = (0.0, 1.0, -1.0), blank: bool = False) -> Scene:
    """Camera at the origin looking down inertial +Z (identity attitude); Didymos on the boresight, Dimorphos
    beside it at ``dimorphos_offset_m`` across the line of sight."""
    did = Body(centre_inertial_m=np.array([0.0, 0.0, range_m]), radius_m=390.0)
    dim = Body(centre_inertial_m=np.array([*dimorphos_offset_m, range_m]), radius_m=82.0)
    return Scene(camera_position_m=np.zeros(3), q_body_to_inertial=np.array([0.0, 0.0, 0.0, 1.0]),
                 body_rate_rad_s=np.zeros(3), exposure_s=0.01, bodies=(did, dim), sun_direction=np.array(sun),
                 blank=blank)


def model(**changes: object) -> CentroidModelConfig:
    """A measurement model without bias, noise, merging or dropout, but for ``changes``."""
    return CentroidModelConfig(**{**PERFECT, **changes})


def pinhole(p: np.ndarray) -> np.ndarray:
    """Closed-form projection of a camera-frame point with the identity attitude."""
    return np.array([C_1024 + F_1024 * p[0] / p[2], C_1024 + F_1024 * p[1] / p[2]])


def test_a_perfect_model_reports_the_pinhole_projection() -> None:
    """Without bias, noise or dropout, the reported centres are the closed-form pinhole projections."""
    sc = scene()
    m = centroid_measurement(sc, CAMERA, model(), np.random.default_rng(1))
    assert m.dimorphos_col_row == pytest.approx(tuple(pinhole(sc.bodies[1].centre_inertial_m)), abs=1e-9)
    assert m.didymos_col_row == pytest.approx(tuple(pinhole(sc.bodies[0].centre_inertial_m)), abs=1e-9)
    r = F_1024 * 82.0 / np.linalg.norm(sc.bodies[1].centre_inertial_m)
    phase = math.degrees(math.acos(-np.array([0, 1, -1]) @ sc.bodies[1].centre_inertial_m
                                   / math.sqrt(2) / np.linalg.norm(sc.bodies[1].centre_inertial_m)))
    assert m.dimorphos_area_px == pytest.approx(math.pi * r * r * (1 + math.cos(math.radians(phase))) / 2, rel=1e-9)


def test_the_bias_moves_the_centroid_towards_the_lit_side() -> None:
    """The bias is the table's fraction of the apparent radius, along the image direction of a step towards the Sun."""
    sc = scene()
    m_cfg = model(phase_deg=(0.0, 180.0), bias_radius_fraction=(0.3, 0.3), dimorphos_dropout=(0.0, 0.0))
    m = centroid_measurement(sc, CAMERA, m_cfg, np.random.default_rng(1))
    centre = sc.bodies[1].centre_inertial_m
    los = centre / np.linalg.norm(centre)
    sun = sc.sun_direction
    step = pinhole(centre + 1.0 * (sun - (sun @ los) * los)) - pinhole(centre)  # the Sun's side, in the image
    shift = np.array(m.dimorphos_col_row) - pinhole(centre)
    radius_px = F_1024 * 82.0 / np.linalg.norm(centre)
    assert np.linalg.norm(shift) == pytest.approx(0.3 * radius_px, rel=1e-6)
    assert shift @ step / (np.linalg.norm(shift) * np.linalg.norm(step)) == pytest.approx(1.0, abs=1e-6)


def test_the_bias_follows_the_phase_table() -> None:
    """Between two table points the bias fraction is interpolated linearly in phase angle."""
    sc = scene()
    _, radius_px, phase, _ = body_view(sc, CAMERA, 1)
    m_cfg = model(phase_deg=(0.0, 180.0), bias_radius_fraction=(0.0, 1.8), dimorphos_dropout=(0.0, 0.0))
    m = centroid_measurement(sc, CAMERA, m_cfg, np.random.default_rng(1))
    shift = np.array(m.dimorphos_col_row) - pinhole(sc.bodies[1].centre_inertial_m)
    assert np.linalg.norm(shift) == pytest.approx(phase / 100.0 * radius_px, rel=1e-6)


def test_noise_has_the_configured_sigma() -> None:
    """Over 4000 frames the per-axis spread is noise_px + noise_radius_fraction * radius (chi-square 5-sigma band)."""
    sc = scene()
    m_cfg = model(noise_px=0.7, noise_radius_fraction=0.5)
    rng = np.random.default_rng(3)
    true = pinhole(sc.bodies[1].centre_inertial_m)
    err = np.array([np.array(centroid_measurement(sc, CAMERA, m_cfg, rng).dimorphos_col_row) - true
                    for _ in range(4000)])
    sigma = 0.7 + 0.5 * F_1024 * 82.0 / np.linalg.norm(sc.bodies[1].centre_inertial_m)
    n = err.size
    assert abs(np.mean(err ** 2) / sigma ** 2 - 1.0) < 5 * math.sqrt(2.0 / n)


def test_dropout_and_misidentification_rates() -> None:
    """The fractions of frames without Dimorphos and with Dimorphos at Didymos's place match the probabilities
    (binomial 5-sigma bands)."""
    sc = scene()
    m_cfg = model(dimorphos_dropout=(0.2,), misidentification=0.1, didymos_dropout=0.05)
    rng = np.random.default_rng(4)
    ms = [centroid_measurement(sc, CAMERA, m_cfg, rng) for _ in range(5000)]
    n = len(ms)
    lost = np.mean([m.dimorphos_col_row is None for m in ms])
    did_lost = np.mean([m.didymos_col_row is None for m in ms])
    swapped = np.mean([m.dimorphos_col_row is not None and m.dimorphos_col_row == m.didymos_col_row for m in ms])
    assert abs(lost - 0.2) < 5 * math.sqrt(0.2 * 0.8 / n)
    assert abs(did_lost - 0.05) < 5 * math.sqrt(0.05 * 0.95 / n)
    p_swap = 0.8 * 0.95 * 0.1  # reported, Didymos reported, then misidentified
    assert abs(swapped - p_swap) < 5 * math.sqrt(p_swap * (1 - p_swap) / n)


def test_misidentifications_come_in_episodes_of_the_mean_length() -> None:
    """Carried from frame to frame, episodes start at the configured rate among frames outside one and last the
    configured mean number of frames (geometric: standard error sqrt(m (m - 1) / episodes))."""
    sc = scene()
    m_cfg = model(misidentification=0.02, misidentification_frames=5.0)
    rng, state = np.random.default_rng(9), MeasurementState()
    ms = [centroid_measurement(sc, CAMERA, m_cfg, rng, state) for _ in range(20000)]
    flags = np.array([m.dimorphos_col_row == m.didymos_col_row for m in ms], dtype=bool)
    p, mean = 0.02, 5.0
    in_episodes = mean * p / (mean * p + 1 - p)  # renewal: episodes of mean length between geometric waits
    assert abs(flags.mean() - in_episodes) < 0.02
    assert np.sum(flags[1:] & ~flags[:-1]) > 150  # they come in runs, not frame by frame
    mean_len = np.mean([episode_frames(5.0, u) for u in np.random.default_rng(10).random(20000)])
    assert abs(mean_len - 5.0) < 5 * math.sqrt(5.0 * 4.0 / 20000)
    assert episode_frames(1.0, 0.99) == 1 and episode_frames(5.0, 0.0) == 1


def test_touching_discs_and_blank_frames_report_no_dimorphos() -> None:
    """Dimorphos merged with Didymos (gap below 2 px in the merge table), out of the frame, or in a blank frame is not
    reported."""
    m_cfg = model(merge_gap_px=(1.9, 2.1), merge_probability=(1.0, 0.0))
    rng = np.random.default_rng(5)
    # discs of 13.1 and 2.8 px at 600 km: 500 m apart is 16.9 px between centres, a gap of 1.0 px
    assert centroid_measurement(scene((500.0, 0.0)), CAMERA, m_cfg, rng).dimorphos_col_row is None
    assert centroid_measurement(scene((1000.0, 0.0)), CAMERA, m_cfg, rng).dimorphos_col_row is not None
    assert centroid_measurement(scene((3000.0, 0.0), blank=True), CAMERA, m_cfg, rng).dimorphos_col_row is None
    outside = centroid_measurement(scene((600_000.0 * 0.03, 0.0)), CAMERA, m_cfg, rng)  # 1.7 deg off: out of 2.9
    assert outside.dimorphos_col_row is None and outside.didymos_col_row is not None


def test_merging_follows_its_table_with_the_dropout() -> None:
    """With a merge probability of 0.5 at the gap and a dropout of 0.2, Dimorphos is reported in 0.5 x 0.8 of the
    frames (binomial 5-sigma band)."""
    sc = scene((1000.0, 0.0))  # a gap of 17.8 px
    m_cfg = model(merge_gap_px=(0.0, 35.6), merge_probability=(1.0, 0.0), dimorphos_dropout=(0.2,))
    rng = np.random.default_rng(8)
    n = 5000
    seen = np.mean([centroid_measurement(sc, CAMERA, m_cfg, rng).dimorphos_col_row is not None for _ in range(n)])
    assert abs(seen - 0.4) < 5 * math.sqrt(0.24 / n)


def test_every_frame_takes_the_same_draws() -> None:
    """A reported and an unreported frame consume the same draws: the next frame's noise is the same."""
    m_cfg = model(noise_px=1.0)
    a, b = np.random.default_rng(6), np.random.default_rng(6)
    centroid_measurement(scene(), CAMERA, m_cfg, a)
    centroid_measurement(scene(blank=True), CAMERA, m_cfg, b)
    assert centroid_measurement(scene(), CAMERA, m_cfg, a) == centroid_measurement(scene(), CAMERA, m_cfg, b)


def test_the_universe_sends_a_measurement_and_no_pixels() -> None:
    """At centroid fidelity a requested frame carries the measurement, an empty blob, and the truth of the frame."""
    sc = Scenario(name="c", seed=2, universe=UniverseConfig(fidelity="centroid", centroid_model=model()))
    u = compose.universe(sc)
    u.begin()
    req, blob = u.advance(StepReply(step=0, wheel_torque_nm=(0.0, 0.0, 0.0),
                                    frame_request=FrameRequest(exposure_s=0.01)))  # type: ignore[misc]
    assert blob == b"" and req.frame is not None and req.frame.measurement is not None
    truth = u.ground_step().truth[-1]  # the period's truth, as ground receives it
    assert truth.frame_id == req.frame.frame_id
    assert truth.dimorphos_px == pytest.approx(req.frame.measurement.dimorphos_col_row, abs=1e-9)


def test_the_measurement_does_not_see_the_bodies_orientation() -> None:
    """The modelled report depends on the bodies' centres and sizes only: turning the bodies changes no draw and no
    value (so the universe builds its measurement scenes without their spin)."""
    sc = scene()
    rng = np.random.default_rng(7)
    turned = Scene(camera_position_m=sc.camera_position_m, q_body_to_inertial=sc.q_body_to_inertial,
                   body_rate_rad_s=sc.body_rate_rad_s, exposure_s=sc.exposure_s, sun_direction=sc.sun_direction,
                   bodies=tuple(Body(centre_inertial_m=b.centre_inertial_m, radius_m=b.radius_m,
                                     q_body_to_inertial=q / np.linalg.norm(q))
                                for b, q in zip(sc.bodies, rng.standard_normal((2, 4)), strict=True)))
    m_cfg = model(noise_px=0.5, noise_radius_fraction=0.05, bias_radius_fraction=(0.2,), dimorphos_dropout=(0.3,))
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    for _ in range(20):
        assert centroid_measurement(sc, CAMERA, m_cfg, a) == centroid_measurement(turned, CAMERA, m_cfg, b)


def test_projecting_camera_vectors_equals_projecting_inertial_points() -> None:
    """``project_camera`` of camera-frame vectors equals ``project_inertial`` of the same points, NaN behind."""
    sc = scene()
    pts = np.array([[10.0, -20.0, 1000.0], [5.0, 5.0, -1000.0]])
    col, row = project_inertial(sc, CAMERA, pts)
    col_c, row_c = project_camera(pts, CAMERA)  # identity attitude: camera frame = inertial frame
    np.testing.assert_array_equal(col, col_c)
    np.testing.assert_array_equal(row, row_c)
    assert math.isnan(col[1]) and math.isnan(project_camera(pts[1], CAMERA)[0])
    assert project_camera(pts[0], CAMERA) == pytest.approx(tuple(pinhole(pts[0])), abs=1e-9)


@settings(max_examples=150, deadline=None)
@given(q=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4), boresight=st.lists(st.floats(-1.0, 1.0), min_size=3,
                                                                                       max_size=3),
       centre=st.lists(st.floats(-1e5, 1e5), min_size=3, max_size=3),
       sun=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_a_body_views_centre_is_the_projection_of_its_centre(q: list[float], boresight: list[float],
                                                           centre: list[float], sun: list[float]) -> None:
    """At any attitude, boresight and place (behind the camera included), the view's centre is ``project_inertial``
    of the body's centre, and its apparent radius and phase angle are the closed forms'."""
    if np.linalg.norm(q) < 0.1 or np.linalg.norm(boresight) < 0.1 or np.linalg.norm(sun) < 0.1 \
            or np.linalg.norm(centre) < 1.0:
        return
    camera = CameraConfig(boresight_body=tuple(np.array(boresight) / np.linalg.norm(boresight)))
    body = Body(centre_inertial_m=np.array(centre), radius_m=82.0)
    sc = Scene(camera_position_m=np.zeros(3), q_body_to_inertial=np.array(q), body_rate_rad_s=np.zeros(3),
               exposure_s=0.01, bodies=(body,), sun_direction=np.array(sun))
    col_row, radius_px, phase_deg, _ = body_view(sc, camera, 0)
    expected = project_inertial(sc, camera, body.centre_inertial_m)
    # NumPy's small products may round a few ulps apart from the compiled view's (tests.numerics): through the
    # projection c + f x / z of a unit vector a rounding of eps moves a point by up to eps f (1 + |x/z|) / |z|
    want = np.array(expected, dtype=float)
    if np.isfinite(want).all():
        f, c = focal_length_px(camera), (camera.resolution_px - 1) / 2.0
        u, v = ((want - c) / f).tolist()
        gain = f * math.hypot(1.0, u, v) * (1.0 + max(abs(u), abs(v)))  # near the camera's plane, unbounded
        assert np.abs(np.asarray(col_row) - want).max() <= 8.0 * np.finfo(float).eps * gain, (col_row, want)
    else:
        assert_within_ulps(col_row, want)
    rng = float(np.linalg.norm(centre))
    assert radius_px == pytest.approx(focal_length_px(camera) * 82.0 / rng, rel=1e-12)
    cos_phase = -float(sc.sun_direction @ (np.array(centre) / rng))
    # compared by cosines: near 0 and 180 deg, acos turns one ulp of a cosine into 1e-6 deg
    assert math.cos(math.radians(phase_deg)) == pytest.approx(min(max(cos_phase, -1.0), 1.0), abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(table=st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-10.0, 10.0)), min_size=1, max_size=12,
                      unique_by=lambda p: p[0]),
       x=st.one_of(st.floats(-1.2e3, 1.2e3), st.sampled_from([math.inf, -math.inf, math.nan])))
def test_interp_is_numpy_s_to_the_bit(table: list[tuple[float, float]], x: float) -> None:
    """``interp`` of one value gives ``np.interp``'s float, bit for bit, on and between the table's points and
    beyond."""
    xp, fp = (tuple(c) for c in zip(*sorted(table), strict=True))
    for v in (x, *xp, *(0.5 * (a + b) for a, b in zip(xp, xp[1:]))):
        want = float(np.interp(v, xp, fp))
        got = interp(v, xp, fp)
        assert got == want or (math.isnan(got) and math.isnan(want)), (v, xp, fp)
        assert math.copysign(1.0, got) == math.copysign(1.0, want)
