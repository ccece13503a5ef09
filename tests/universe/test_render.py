"""Perfect-pointing frames (``universe.render``) and the ``flyby render`` command."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from PIL import Image
from scipy.spatial.transform import Rotation

from flyby.cli import main as flyby_main
from scenario.model import Scenario, load_scenario
from universe.camera import sensor_defects
from universe.config import BodiesConfig, FlybyConfig, UniverseConfig
from universe.geometry import FlybyGeometry
from universe.render import (
    PerfectPointingCamera,
    RenderRequestError,
    display_frame,
    perfect_pointing,
    render_times_s,
)
from universe.simulator import pointing_attitude
from scenario import compose

unit_vectors = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: 0.2 < math.dist(v, (0, 0, 0)))


def geometry_of(approach: tuple, ca: tuple, normal: tuple, distance_km: float) -> FlybyGeometry:
    """A flyby geometry with the given directions and C/A distance (other values default)."""
    return FlybyGeometry(
        FlybyConfig(approach_direction=approach, ca_direction=ca, ca_distance_km=distance_km),
        BodiesConfig(orbit_normal=normal),
    )


def not_parallel(a: tuple, b: tuple) -> bool:
    """Whether a and b are at least ~6 deg from parallel (the C/A direction must have a part across the velocity)."""
    return float(np.linalg.norm(np.cross(a, b))) > 0.1 * math.dist(a, (0, 0, 0)) * math.dist(b, (0, 0, 0))


@settings(max_examples=40, deadline=None)
@given(approach=unit_vectors, ca=unit_vectors, normal=unit_vectors, distance_km=st.floats(20.0, 200.0),
       t_s=st.floats(-300.0, 400.0))
def test_perfect_pointing_puts_dimorphos_on_the_boresight(approach, ca, normal, distance_km, t_s) -> None:
    """The Dimorphos centre, pinhole-projected by hand with the perfect attitude, lies on the boresight (+Z)."""
    assume(not_parallel(approach, ca))
    g = geometry_of(approach, ca, normal, distance_km)
    p = perfect_pointing(g, t_s)
    rel = g.dimorphos_position_m(t_s) - g.spacecraft_position_m(t_s)
    v_body = Rotation.from_quat(p.q).as_matrix().T @ rel
    assert v_body[2] > 0
    assert abs(v_body[0] / v_body[2]) < 1e-12 and abs(v_body[1] / v_body[2]) < 1e-12
    # default roll: body +X leans against the velocity, so body +Y lies on the flyby-plane side of e_ca x e_v
    x_inertial, y_inertial = Rotation.from_quat(p.q).apply([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert x_inertial @ g.e_v <= 1e-12
    assert y_inertial @ np.cross(g.e_ca, g.e_v) >= -1e-9


@settings(max_examples=40, deadline=None)
@given(approach=unit_vectors, ca=unit_vectors, normal=unit_vectors, distance_km=st.floats(20.0, 200.0),
       t_s=st.floats(-300.0, 400.0), ref=unit_vectors)
def test_perfect_pointing_rate_is_the_derivative_of_the_attitude(approach, ca, normal, distance_km, t_s, ref) -> None:
    """The body rate equals the central finite difference of pointing_attitude over +-1 ms (line of sight and roll)."""
    assume(not_parallel(approach, ca))
    g = geometry_of(approach, ca, normal, distance_km)
    h = 1e-3
    roll_ref = np.asarray(ref, dtype=float)
    los = g.dimorphos_position_m(t_s) - g.spacecraft_position_m(t_s)
    # a reference within ~11 deg of the line of sight rolls so fast that the 1 ms difference itself is inexact
    assume(float(np.linalg.norm(np.cross(roll_ref, los))) > 0.2 * float(np.linalg.norm(roll_ref * np.linalg.norm(los))))

    def att(t: float) -> Rotation:
        rel = g.dimorphos_position_m(t) - g.spacecraft_position_m(t)
        return pointing_attitude(rel / np.linalg.norm(rel), roll_ref)

    # inertial angular velocity from R(t+h) R(t-h)^-1 = exp(2 h [w]x); then into body axes at t
    w_inertial = (att(t_s + h) * att(t_s - h).inv()).as_rotvec() / (2 * h)
    w_body = att(t_s).inv().apply(w_inertial)
    p = perfect_pointing(g, t_s, roll_ref)
    # truncation ~ h^2 * third derivative (< 1e-9 rad/s at these ranges); rounding ~ 1e-16 / h on positions of 1e6 m
    np.testing.assert_allclose(p.omega_body_rad_s, w_body, atol=1e-9 + 1e-6 * float(np.linalg.norm(w_body)))


def test_perfect_pointing_rate_at_ca_is_speed_over_distance() -> None:
    """At C/A with Dimorphos' motion negligible, the pointing turns at v / b about the flyby-plane normal."""
    g = geometry_of((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), 55.0)
    t = g.ca_time_s
    p = perfect_pointing(g, t)
    rel = g.dimorphos_position_m(t) - g.spacecraft_position_m(t)
    closed_form = 7000.0 / float(np.linalg.norm(rel))  # straight line past a point: rate v/r at C/A
    assert float(np.linalg.norm(p.omega_body_rad_s)) == pytest.approx(closed_form, rel=2e-3)  # Dimorphos' 0.17 m/s


def test_render_times_cover_the_window_inclusively() -> None:
    """Times start at from, step by every, and include to when it lies on the grid (to a microsecond)."""
    np.testing.assert_allclose(render_times_s(-132.0, 288.0, 1.0), np.arange(-132.0, 288.5, 1.0))
    np.testing.assert_allclose(render_times_s(0.0, 1.0, 0.3), [0.0, 0.3, 0.6, 0.9])
    np.testing.assert_allclose(render_times_s(5.0, 5.0, 2.0), [5.0])
    with pytest.raises(RenderRequestError, match="--every"):
        render_times_s(0.0, 1.0, 0.0)
    with pytest.raises(RenderRequestError, match="--from"):
        render_times_s(2.0, 1.0, 1.0)


def test_frames_are_centred_on_dimorphos_and_deterministic() -> None:
    """A perfect-pointing frame has Dimorphos' true pixel at the principal point, and the same scenario repeats it."""
    scenario = Scenario(name="render", seed=4)
    a = PerfectPointingCamera(compose.universe(scenario)).frame_at(120.0)
    b = PerfectPointingCamera(compose.universe(scenario)).frame_at(120.0)
    c = (scenario.universe.camera.resolution_px - 1) / 2.0
    assert a.dimorphos_px == pytest.approx((c, c), abs=1e-6)
    assert a.pixels.dtype == np.uint16 and a.pixels.shape == (1024, 1024)
    np.testing.assert_array_equal(a.pixels, b.pixels)
    # Dimorphos (~10 px across at 340 km) is lit above the dark level where the boresight is
    centre = a.pixels[508:516, 508:516].astype(float)
    assert centre.max() > scenario.universe.camera.dark_offset_dn + 200


def test_display_frame_is_8_bit_at_the_asked_size() -> None:
    """display_frame returns uint8 at size x size, bright where the frame is bright."""
    frame = np.full((1024, 1024), 64, dtype=np.uint16)
    frame[:512, :] = 3000
    img = display_frame(frame, 12, 256)
    assert img.shape == (256, 256) and img.dtype == np.uint8
    assert img[:100].min() > img[160:].max()
    with pytest.raises(RenderRequestError, match="--size"):
        display_frame(frame, 12, 0)


def write_scenario(tmp_path: Path, text: str) -> Path:
    """A scenario file in tmp_path."""
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def test_flyby_render_writes_pngs_and_a_gif(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`flyby render --from 100 --to 102 --every 1` writes 3 PNGs of --size and a 3-frame GIF, and says so."""
    path = write_scenario(tmp_path, "name: short\nseed: 2\nuniverse:\n  start_s: 90.0\n  end_s: 130.0\n")
    out = tmp_path / "frames"
    code = flyby_main(["render", str(path), "--out", str(out), "--from", "100", "--to", "102", "--every", "1",
                       "--size", "128", "--gif-size", "64"])
    assert code == 0
    pngs = sorted(out.glob("frame_*.png"))
    assert [p.name for p in pngs] == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    for p in pngs:
        with Image.open(p) as im:
            assert im.size == (128, 128) and im.mode == "L"
    with Image.open(out / "render.gif") as gif:
        assert gif.n_frames == 3 and gif.size == (64, 64)
    said = capsys.readouterr()
    assert "3 frames" in said.out and str(out) in said.out
    assert "frame 3/3" in said.err


def test_flyby_render_rejects_bad_scenarios_and_windows(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An invalid scenario or an empty window exits 2 with the problem named, writing nothing."""
    bad = write_scenario(tmp_path, "name: bad\nuniverse:\n  camera:\n    fov_deg: -1\n")
    out = tmp_path / "frames"
    assert flyby_main(["render", str(bad), "--out", str(out)]) == 2
    assert "universe.camera.fov_deg" in capsys.readouterr().err
    good = tmp_path / "good.yaml"
    good.write_text("name: good\n")
    assert flyby_main(["render", str(good), "--out", str(out), "--from", "10", "--to", "5"]) == 2
    assert "--from" in capsys.readouterr().err
    assert not out.exists()


def test_flyby_render_defaults_to_the_run_at_the_frame_period(tmp_path: Path) -> None:
    """Without --from/--to/--every the frames span start_s..end_s inclusive at the camera frame period."""
    path = write_scenario(tmp_path, "name: tiny\nuniverse:\n  start_s: 100.0\n  end_s: 101.0\n"
                                    "  camera:\n    frame_period_s: 0.5\n")
    out = tmp_path / "frames"
    assert flyby_main(["render", str(path), "--out", str(out), "--size", "64"]) == 0
    assert len(list(out.glob("frame_*.png"))) == 3


def test_the_detector_scenario_renders_a_valid_frame_at_closest_approach() -> None:
    """configs/scenarios/detector.yaml (a degraded detector, every effect on): at C/A the frame has its
    size and bit depth, Dimorphos lit on the boresight, the dead column at the bias; the scenario is the same
    flyby as the nominal scenario but for the camera."""
    root = Path(__file__).parents[2] / "configs" / "scenarios"
    detector, nominal = load_scenario(root / "detector.yaml"), load_scenario(root / "nominal.yaml")
    cam = detector.universe.camera
    assert cam.cosmic_ray_flux_cm2_s > 0 and cam.dark_current_dsnu_e_s > 0 and cam.warm_pixel_fraction > 0
    assert cam.dead_pixel_count > 0 and cam.dead_column_count > 0
    assert detector.universe.model_copy(update={"camera": nominal.universe.camera}) == nominal.universe
    ca_s = detector.universe.flyby.ca_time_s
    frame = PerfectPointingCamera(compose.universe(detector)).frame_at(ca_s).pixels
    assert frame.dtype == np.uint16 and frame.shape == (1024, 1024) and int(frame.max()) <= 4095
    assert frame[508:516, 508:516].mean() > cam.dark_offset_dn + 200
    assert np.all(frame[:, sensor_defects(cam).dead_columns] == round(cam.dark_offset_dn))
