"""The fit of the centroid-level measurement model: it recovers the parameters of frames the model itself made."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.scoring import binned_px
from flyby.montecarlo.centroidfit import FrameSamples, fit_model, full_resolution
from universe.camera import Body, Scene
from universe.config import CameraConfig, CentroidModelConfig
from universe.measurement import MeasurementState, body_view, centroid_measurement

CAMERA = CameraConfig()
TRUE = CentroidModelConfig(phase_deg=(0.0, 180.0), bias_radius_fraction=(0.1, 0.7), dimorphos_dropout=(0.05, 0.25),
                           noise_px=0.8, noise_radius_fraction=0.05, merge_gap_px=(0.0, 12.0),
                           merge_probability=(1.0, 0.0), didymos_dropout=0.1,
                           misidentification=0.005, misidentification_frames=4.0)


@given(x=st.floats(0, 511), y=st.floats(0, 511), factor=st.sampled_from([2.0, 4.0]))
def test_full_resolution_inverts_the_binning(x: float, y: float, factor: float) -> None:
    """A binned position taken back to full resolution bins to itself (analysis.scoring.binned_px)."""
    full = np.array(full_resolution((x, y), factor))
    assert binned_px(full, factor) == pytest.approx([x, y], abs=1e-9)


def synthetic_samples(n: int, seed: int) -> FrameSamples:
    """Frames of random geometry (range, place in the image, Dimorphos's offset, the Sun) measured by TRUE, in
    runs of 300 frames (an episode carries on from frame to frame within a run)."""
    rng = np.random.default_rng(seed)
    state = MeasurementState()
    rows: dict[str, list] = {k: [] for k in ("td", "ti", "rd", "ri", "rad_d", "rad_i", "ph", "sun")}
    for _ in range(n):
        rng_m = rng.uniform(60e3, 600e3)
        did = np.array([*rng.uniform(-0.015, 0.015, 2) * rng_m, rng_m])
        offset = rng.uniform(0.3e3, 3e3) * np.array([math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a), 0.0])
        sun = rng.standard_normal(3)
        scene = Scene(camera_position_m=np.zeros(3), q_body_to_inertial=np.array([0, 0, 0, 1.0]),
                      body_rate_rad_s=np.zeros(3), exposure_s=0.01, sun_direction=sun / np.linalg.norm(sun),
                      bodies=(Body(centre_inertial_m=did, radius_m=390.0),
                              Body(centre_inertial_m=did + offset, radius_m=82.0)))
        if len(rows["td"]) % 300 == 0:
            state = MeasurementState()
        m = centroid_measurement(scene, CAMERA, TRUE, rng, state)
        p_did, r_did, _, _ = body_view(scene, CAMERA, 0)
        p_dim, r_dim, ph, towards = body_view(scene, CAMERA, 1)
        nan = (np.nan, np.nan)
        for k, v in (("td", p_dim), ("ti", p_did), ("rd", m.dimorphos_col_row or nan),
                     ("ri", m.didymos_col_row or nan), ("rad_d", r_dim), ("rad_i", r_did), ("ph", ph), ("sun", towards)):
            rows[k].append(v)
    a = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    return FrameSamples(a["td"], a["ti"], a["rd"], a["ri"], a["rad_d"], a["rad_i"], a["ph"], a["sun"],
                        np.arange(n) // 300, CAMERA.resolution_px)


def test_the_fit_recovers_the_model_that_made_the_frames() -> None:
    """On 6000 frames measured by a known model, the fit finds its bias and dropout against phase, its noise law,
    merge table and rates within their sampling errors."""
    fitted, _ = fit_model(synthetic_samples(6000, 1), tolerance_px=30.0)
    phases = np.array(fitted.phase_deg)
    assert phases.size >= 10
    np.testing.assert_allclose(fitted.bias_radius_fraction, np.interp(phases, (0, 180), (0.1, 0.7)), atol=0.08)
    np.testing.assert_allclose(fitted.dimorphos_dropout, np.interp(phases, (0, 180), (0.05, 0.25)), atol=0.12)
    gaps = np.array(fitted.merge_gap_px)
    np.testing.assert_allclose(fitted.merge_probability, np.interp(gaps, (0.0, 12.0), (1.0, 0.0)), atol=0.15)
    assert gaps.min() < 0.0 and gaps.max() > 12.0
    assert fitted.noise_px == pytest.approx(0.8, abs=0.25)
    assert fitted.noise_radius_fraction == pytest.approx(0.05, abs=0.015)
    assert fitted.didymos_dropout == pytest.approx(0.1, abs=5 * math.sqrt(0.1 * 0.9 / 6000))
    assert fitted.misidentification == pytest.approx(0.005, abs=0.003)
    assert fitted.misidentification_frames == pytest.approx(4.0, abs=1.5)


def test_samples_kept_on_disk_come_back_equal(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Samples saved and loaded again are the same arrays, so a refit from disk fits the same model."""
    s = synthetic_samples(400, 2)
    s.save(tmp_path / "run-00000.npz")
    back = FrameSamples.load(tmp_path / "run-00000.npz")
    for name, value in vars(s).items():
        np.testing.assert_array_equal(getattr(back, name), value)
    assert not list(tmp_path.glob("*.part"))


def test_the_shipped_fits_are_models_flyby_mc_takes() -> None:
    """Every model file in configs/centroid-models is one ``flyby mc --centroid-model`` accepts."""
    from pathlib import Path

    from flyby.montecarlo.campaign import centroid_model_file

    files = sorted((Path(__file__).parents[2] / "configs" / "centroid-models").glob("*.yaml"))
    assert files
    for path in files:
        CentroidModelConfig(**centroid_model_file(path))
