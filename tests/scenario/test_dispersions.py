"""Dispersions: refused at load with their path when they cannot apply, drawn from (campaign seed, k) only, with the
distributions they declare, and the drawn values reach the cores that use them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from contracts.errors import ScenarioError
from contracts.sdls import KeyRing
from scenario import compose
from scenario.dispersions import Dispersion, draw, dispersed_run, run_seeds
from scenario.model import Scenario, scenario_from_dict
from universe.camera import hot_pixels
from universe.config import FlybyConfig
from universe.geometry import dimorphos_line
from universe.scene import scene_at
from universe.simulator import pointing_attitude

N_DRAWS = 4000


def with_dispersions(*entries: dict[str, Any], **top: Any) -> Scenario:
    """The default scenario with these dispersion entries (and top-level fields)."""
    return scenario_from_dict({"name": "mc", "seed": 11, **top, "dispersions": list(entries)})


def problems(*entries: dict[str, Any]) -> list[str]:
    """The load problems of the default scenario with these dispersion entries."""
    with pytest.raises(ScenarioError) as err:
        with_dispersions(*entries)
    return err.value.problems


def test_bad_paths_are_refused_naming_the_entry() -> None:
    """Each entry whose path names no dispersable field is one line opening with dispersions[i].path."""
    lines = problems({"path": "universe.bodies.orbit_phase", "normal": {"sigma": 1.0}},
                     {"path": "obsw.inertia_kgm2", "normal": {"sigma": 0.01}},
                     {"path": "universe.camera.fov_deg", "direction": {"sigma_deg": 1.0}},
                     {"path": "universe..x", "normal": {"sigma": 1.0}},
                     {"path": "universe.faults[0].start_s", "normal": {"sigma": 1.0}},
                     {"path": "universe.plume.enabled", "normal": {"sigma": 1.0}},
                     {"path": "universe.camera", "normal": {"sigma": 1.0}},
                     {"path": "seed", "uniform": {"low": 0, "high": 9}})
    assert [line.split(":", 1)[0] for line in lines] == [f"dispersions[{i}].path" for i in range(8)]
    assert "universe.bodies has no field 'orbit_phase'" in lines[0] and "orbit_phase_deg" in lines[0]
    assert "disperse its elements by index" in lines[1]
    assert "a direction disperses a 3-vector" in lines[2]
    assert "is not a field path" in lines[3]
    assert "has no element [0] (0 elements)" in lines[4]
    assert "True is not a number" in lines[5]
    assert "a section" in lines[6]
    assert "not dispersable" in lines[7]


def test_bad_distributions_are_refused() -> None:
    """A negative sigma, reversed bounds, no or two distributions, and a field dispersed twice are refused."""
    assert problems({"path": "universe.bodies.orbit_phase_deg", "normal": {"sigma": -1.0}}) == [
        "dispersions[0].normal.sigma: must be > 0"]
    assert problems({"path": "universe.bodies.orbit_phase_deg", "uniform": {"low": 1.0, "high": 0.0}}) == [
        "dispersions[0].uniform.high: 0 must be above low 1"]
    assert "exactly one distribution" in problems({"path": "universe.bodies.orbit_phase_deg"})[0]
    assert "exactly one distribution" in problems({"path": "universe.bodies.orbit_phase_deg", "normal": {
        "sigma": 1.0}, "uniform": {"low": 0.0, "high": 1.0}})[0]
    twice = problems({"path": "obsw.inertia_kgm2[0][0]", "normal": {"sigma": 0.01}},
                     {"path": "obsw.inertia_kgm2[0]", "normal": {"sigma": 0.01}})
    assert twice == ["dispersions[1].path: 'obsw.inertia_kgm2[0]' overlaps dispersions[0] 'obsw.inertia_kgm2[0][0]': "
                     "a field is dispersed once"]


def test_a_run_depends_on_the_campaign_seed_and_its_index_only() -> None:
    """Run k's draw is the same whenever it is made; other k and other campaign seeds differ; appending an entry
    leaves the draws of the others unchanged."""
    phase = {"path": "universe.bodies.orbit_phase_deg", "uniform": {"low": 0.0, "high": 360.0}}
    rate = {"path": "universe.spacecraft.initial_rate_deg_s", "normal": {"sigma": 0.1}}
    base = with_dispersions(phase)
    again = [dispersed_run(base, 7, k) for k in (3, 1, 2)]
    alone = dispersed_run(base, 7, 2)
    assert alone.scenario == again[2].scenario and alone.values == again[2].values
    assert len({r.scenario.seed for r in again}) == 3
    assert dispersed_run(base, 8, 2).values != alone.values
    longer = dispersed_run(with_dispersions(phase, rate), 7, 2)
    assert longer.values["universe.bodies.orbit_phase_deg"] == alone.values["universe.bodies.orbit_phase_deg"]
    assert longer.scenario.seed == alone.scenario.seed


def _draws(entry: dict[str, Any], nominal: Any) -> list[Any]:
    d = Dispersion.model_validate(entry)
    return [draw(d, nominal, run_seeds(5, k, 1)[1][0])[0] for k in range(N_DRAWS)]


def test_normal_draws_have_their_mean_sigma_and_truncation() -> None:
    """About the nominal: mean and sigma within 5 standard errors; truncated draws stay within the bound and have
    the truncated normal's variance; relative draws scale the nominal."""
    x = np.array(_draws({"path": "a", "normal": {"sigma": 2.0}}, 10.0))
    assert abs(x.mean() - 10.0) < 5 * 2.0 / math.sqrt(N_DRAWS)
    assert abs(x.std() / 2.0 - 1.0) < 5 / math.sqrt(2 * N_DRAWS)
    t = np.array(_draws({"path": "a", "normal": {"sigma": 2.0, "truncate_sigma": 1.0, "mean": 0.0}}, 10.0))
    assert np.all(np.abs(t) <= 2.0)
    var_trunc = 1 - 2 * math.exp(-0.5) / math.sqrt(2 * math.pi) / math.erf(1 / math.sqrt(2))  # at +-1 sigma
    assert abs(t.var() / (4.0 * var_trunc) - 1.0) < 0.1
    r = np.array(_draws({"path": "a", "normal": {"sigma": 0.1, "relative": True}}, 50.0))
    assert abs(r.mean() - 50.0) < 5 * 5.0 / math.sqrt(N_DRAWS) and abs(r.std() / 5.0 - 1.0) < 0.06


def test_uniform_and_integer_draws() -> None:
    """Uniform draws fill their bounds with the uniform mean; an integer field gets whole numbers."""
    u = np.array(_draws({"path": "a", "uniform": {"low": -1.0, "high": 3.0}}, 0.0))
    assert u.min() >= -1.0 and u.max() <= 3.0 and abs(u.mean() - 1.0) < 5 * 4 / math.sqrt(12 * N_DRAWS)
    n = _draws({"path": "a", "uniform": {"low": 0, "high": 10}}, 50)
    assert all(isinstance(v, int) for v in n) and set(n) <= set(range(11)) and len(set(n)) == 11


def test_direction_draws_turn_by_a_normal_angle_and_keep_the_length() -> None:
    """A direction draw keeps the vector's length; the angle to the nominal is |N(0, sigma)| (mean sigma sqrt(2/pi))
    and equals the recorded angle; the turn's azimuth is uniform (mean of the unit offsets near zero)."""
    d = Dispersion.model_validate({"path": "v", "direction": {"sigma_deg": 2.0}})
    nominal = [0.0, 0.0, 2.0]
    angles, offsets = [], []
    for k in range(N_DRAWS):
        v, cols = draw(d, nominal, run_seeds(9, k, 1)[1][0])
        assert np.linalg.norm(v) == pytest.approx(2.0, rel=1e-12)
        a = math.degrees(math.acos(np.clip(v[2] / 2.0, -1, 1)))
        assert a == pytest.approx(cols["v.angle_deg"], abs=1e-6)
        angles.append(a)
        offsets.append(np.array(v[:2]) / max(np.hypot(*v[:2]), 1e-300))
    assert abs(np.mean(angles) / (2.0 * math.sqrt(2 / math.pi)) - 1.0) < 0.05
    assert np.linalg.norm(np.mean(offsets, axis=0)) < 5 / math.sqrt(N_DRAWS)


def test_dispersed_knowledge_is_declared_a_knowledge_error() -> None:
    """Dispersing on-board knowledge, or a truth the spacecraft knows, adds the knowing path to knowledge_errors;
    a truth nobody knows adds nothing."""
    run = dispersed_run(with_dispersions(
        {"path": "obsw.inertia_kgm2[1][1]", "normal": {"sigma": 0.05, "relative": True}},
        {"path": "universe.camera.boresight_body", "direction": {"sigma_deg": 0.1}},
        {"path": "universe.bodies.orbit_phase_deg", "normal": {"sigma": 5.0}}), 1, 0)
    assert set(run.scenario.knowledge_errors) == {"obsw.inertia_kgm2", "obsw.camera.boresight_body"}
    assert run.scenario.dispersions == () and run.scenario.name == "mc-run00000"


# --- the drawn values reach the components ------------------------------------------------------------------------


def _angle_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    return math.degrees((Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude())


def _orbit_phase_deg(u: Any) -> float:
    g = u.geometry
    p = g.dimorphos_position_m(0.0)
    return math.degrees(math.atan2(p @ g.orbit_e2, p @ g.orbit_e1)) % 360.0


def _to_dimorphos(sc: Scenario) -> FlybyConfig:
    """The run's true flyby of Dimorphos, which ground's belief is of (its velocity, a dispersed truth, included)."""
    return dimorphos_line(sc.universe.flyby, sc.universe.bodies)


REACH: list[tuple[str, dict[str, Any], Any]] = [
    # (path, distribution, (fsw, universe, ground, drawn value, scenario) -> (value inside the component, expected))
    ("universe.uncertainty.ca_time_offset_sigma", {"normal": {"sigma": 1.0, "mean": 0.0}},
     lambda f, u, g, v, s: (g.belief.ca_utc_s,
                            _to_dimorphos(s).ca_time_s + v * s.universe.uncertainty.ca_time_sigma_s)),
    ("universe.uncertainty.ca_distance_offset_sigma", {"normal": {"sigma": 1.0, "mean": 0.0}},
     lambda f, u, g, v, s: (g.belief.ca_distance_km,
                            _to_dimorphos(s).ca_distance_km + v * s.universe.uncertainty.ca_distance_sigma_km)),
    ("universe.flyby.approach_direction", {"direction": {"sigma_deg": 2.0}},
     lambda f, u, g, v, s: ((*u.geometry.e_v, *g.belief.approach_direction),
                            (*v, *_to_dimorphos(s).approach_direction))),
    ("universe.sensors.star_tracker.noise_arcsec", {"normal": {"sigma": 0.2, "relative": True}},
     lambda f, u, g, v, s: (u.sensors._st_sigma_rad, np.radians(np.array(v) / 3600))),
    ("universe.sensors.star_tracker.bias_arcsec", {"normal": {"sigma": 5.0}},
     lambda f, u, g, v, s: (u.sensors._st_bias_rad, np.radians(np.array(v) / 3600))),
    ("universe.sensors.gyro.initial_bias_deg_h", {"normal": {"sigma": 1.0}},
     lambda f, u, g, v, s: (u.sensors.gyro_bias_rad_s, np.radians(np.array(v) / 3600))),
    ("universe.sensors.gyro.arw_deg_sqrt_h", {"normal": {"sigma": 0.1, "relative": True}},
     lambda f, u, g, v, s: (u.sensors._arw_rad_sqrt_s, math.radians(v) / 60)),
    ("universe.camera.boresight_body", {"direction": {"sigma_deg": 0.5}},
     lambda f, u, g, v, s: ((*u._boresight, *f.camera.boresight_body), (*v, 0.0, 0.0, 1.0))),
    ("universe.camera.read_noise_e", {"normal": {"sigma": 0.2, "relative": True}},
     lambda f, u, g, v, s: (u.cfg.camera.read_noise_e, v)),
    ("obsw.inertia_kgm2[2][2]", {"normal": {"sigma": 0.02, "relative": True}},
     lambda f, u, g, v, s: ((f.inertia[2, 2], u.dynamics.sc.inertia_kgm2[2][2]), (v, 0.058))),
    ("universe.spacecraft.wheels.viscous_friction_nms", {"normal": {"sigma": 0.3, "relative": True}},
     lambda f, u, g, v, s: (u.dynamics._viscous, v)),
    ("universe.spacecraft.wheels.coulomb_friction_nm", {"normal": {"sigma": 0.3, "relative": True}},
     lambda f, u, g, v, s: (u.dynamics._coulomb, v)),
    ("universe.spacecraft.initial_attitude_error_deg", {"uniform": {"low": 0.5, "high": 2.0}},
     lambda f, u, g, v, s: (_angle_deg(u.state.q, pointing_attitude(
         u.geometry.truth_sample(u.t_s, np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0]), 90.0).los_dimorphos_inertial,
         -u.geometry.e_v).as_quat()), v)),
    ("universe.spacecraft.initial_rate_deg_s", {"normal": {"sigma": 0.05}},
     lambda f, u, g, v, s: (u.state.omega_rad_s, np.radians(v))),
    ("universe.oscillator.initial_offset_s", {"normal": {"sigma": 0.01}},
     lambda f, u, g, v, s: (u.oscillator.obt_mean_s(0.0), v)),
    ("universe.oscillator.drift_ppm", {"normal": {"sigma": 1.0}},
     lambda f, u, g, v, s: (u.oscillator._d, v * 1e-6)),
    ("universe.plume.reflectance_factor", {"normal": {"sigma": 0.3, "relative": True}},
     lambda f, u, g, v, s: (u.cfg.plume.reflectance_factor, v)),
    ("universe.plume.axis_inertial", {"direction": {"sigma_deg": 10.0}},
     lambda f, u, g, v, s: (u.cfg.plume.axis_inertial, v)),
    ("universe.camera.body_signal_e_s", {"normal": {"sigma": 0.1, "relative": True}},
     lambda f, u, g, v, s: (u.cfg.camera.body_signal_e_s, v)),
    ("universe.bodies.dimorphos_diameter_m", {"normal": {"sigma": 8.0}},
     lambda f, u, g, v, s: (scene_at(u, 0.01).bodies[1].radius_m, v / 2)),
    ("universe.bodies.orbit_phase_deg", {"uniform": {"low": 0.0, "high": 360.0}},
     lambda f, u, g, v, s: (_orbit_phase_deg(u), v)),
    ("universe.camera.hot_pixel_count", {"uniform": {"low": 0, "high": 200}},
     lambda f, u, g, v, s: (hot_pixels(u.cfg.camera.hot_pixel_seed, u.cfg.camera.hot_pixel_count,
                                       u.cfg.camera.resolution_px, u.cfg.camera.hot_pixel_signal_e)[0].size, v)),
]


@pytest.mark.parametrize(("path", "distribution", "inside"), REACH, ids=[r[0] for r in REACH])
def test_the_drawn_value_reaches_the_component(path: str, distribution: dict[str, Any], inside: Any) -> None:
    """Composed from a dispersed run, the flight software, universe or ground holds the value drawn for it."""
    run = dispersed_run(with_dispersions({"path": path, **distribution}), 3, 1)
    sc = run.scenario
    if path.endswith(("approach_direction", "boresight_body", "axis_inertial")):
        drawn: Any = [run.values[f"{path}[{i}]"] for i in range(3)]
        assert run.values[f"{path}.angle_deg"] > 0
    elif path.endswith(("noise_arcsec", "bias_arcsec", "initial_bias_deg_h", "initial_rate_deg_s")):
        drawn = [run.values[f"{path}[{i}]"] for i in range(3)]
    else:
        drawn = run.values[path]
    got, expected = inside(compose.flight_software(sc, KeyRing.derived(sc.seed)), compose.universe(sc),
                           compose.ground_segment(sc), drawn, sc)
    norm = np.linalg.norm(np.atleast_1d(np.asarray(expected, dtype=float)))
    np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(expected, dtype=float), rtol=1e-9,
                               atol=1e-12 * max(norm, 1.0))
    nominal = Scenario(name="mc", seed=sc.seed)  # the value differs from the nominal one: the test can fail
    n_got, _ = inside(compose.flight_software(nominal, KeyRing.derived(nominal.seed)), compose.universe(nominal),
                      compose.ground_segment(nominal), drawn, nominal)
    assert not np.allclose(np.asarray(n_got, dtype=float), np.asarray(got, dtype=float), rtol=1e-12, atol=0)
