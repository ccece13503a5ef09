"""The compiled attitude integrator: cached next to its source, so later processes do not recompile it; a control
period in one compiled call gives the bits of the NumPy composition of its substeps."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tests.numerics import assert_within_ulps
from universe import attitude_rk4
from universe.config import SpacecraftConfig
from universe.dynamics import SpacecraftDynamics

ROOT = Path(__file__).resolve().parents[2]

_PROBE = """
import json
import math
from universe import attitude_rk4
attitude_rk4.warm_up()
s = attitude_rk4.integrate.stats
print(json.dumps([s.cache_path, len(s.cache_hits), len(s.cache_misses)]))
"""


def test_a_new_process_loads_the_integrator_from_the_cache_next_to_its_source() -> None:
    """After one warm-up, a fresh process's warm-up only hits the cache in universe/__pycache__."""
    attitude_rk4.warm_up()  # writes the cache if this process compiled the kernel
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120, check=True)
    path, hits, misses = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(path) == Path(attitude_rk4.__file__).parent / "__pycache__"
    assert hits > 0 and misses == 0, (hits, misses)


def _period_in_numpy(dyn: SpacecraftDynamics, q: np.ndarray, w: np.ndarray, h: np.ndarray, u_before: np.ndarray,
                     u_cmd: np.ndarray, switch_s: float, dt_s: float, motor_on: np.ndarray,
                     stuck: frozenset[int]) -> np.ndarray:
    """The period as the dynamics wrote it before it was one compiled call: NumPy around one integrator call per
    held torque."""
    mode = dyn._mode(stuck)
    x = np.concatenate((q, w, h))
    for u, span_s in ((u_before, switch_s), (u_cmd, dt_s - switch_s)) if switch_s > 0.0 else ((u_cmd, dt_s),):
        u_held = np.minimum(np.maximum(u, -dyn.max_torque_nm), dyn.max_torque_nm) * motor_on
        n_sub = 0 if span_s == 0.0 else max(math.ceil(span_s / dyn._max_substep_s - 1e-9),
                                            math.ceil(span_s * dyn._friction_rate_s / 0.5))
        hs = span_s / n_sub if n_sub else 0.0
        x = attitude_rk4.integrate(x, u_held, mode.free_axes, mode.gain, mode.i_eff_flat, mode.i_eff_inv_flat,
                                   dyn.rotor_inertia_kgm2, dyn.max_momentum_nms, dyn._viscous, dyn._coulomb,
                                   1.0 / dyn._smooth, n_sub, hs)
    speeds = (x[7:] / dyn.rotor_inertia_kgm2 - dyn.wheel_axes_body.T @ x[4:7]) * mode.free
    return np.concatenate((x[:7], speeds))


def _speed_terms(dyn: SpacecraftDynamics, expected: np.ndarray) -> float:
    """A bound of the terms the rotor speeds are differences of, the rotor's momentum over its inertia and the body
    rate along its axis (the first is the speed plus the second): their rounding is the speeds'."""
    along = np.abs(dyn.wheel_axes_body.T @ expected[4:7]).max(initial=0.0)
    return float(np.abs(expected[7:]).max(initial=0.0) + along)


_DYNAMICS = {layout: SpacecraftDynamics(SpacecraftConfig.model_validate({"wheels": {"layout": layout}}))
             for layout in ("orthogonal", "pyramid")}
_finite = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(layout=st.sampled_from(sorted(_DYNAMICS)), q=st.lists(_finite, min_size=4, max_size=4),
       w=st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3), h=st.lists(st.floats(-0.05, 0.05), min_size=4,
                                                                           max_size=4),
       u=st.lists(st.floats(-0.01, 0.01), min_size=8, max_size=8), switch=st.sampled_from([0.0, 0.0, 0.004, 0.1]),
       dt_s=st.sampled_from([0.1, 0.05, 0.5]), off=st.lists(st.booleans(), min_size=4, max_size=4),
       stuck=st.sets(st.integers(0, 3), max_size=2))
@example(layout="pyramid", q=[0.0, 0.0, 0.0, 0.0], w=[0.1875, -0.125, 0.0], h=[0.0] * 4, u=[0.0] * 8, switch=0.0,
         dt_s=0.5, off=[False] * 4, stuck={1, 3})  # still wheels: speeds of 0.0017 from terms of 0.13
def test_one_compiled_period_gives_the_bits_of_its_numpy_composition(
        layout: str, q: list[float], w: list[float], h: list[float], u: list[float], switch: float, dt_s: float,
        off: list[bool], stuck: set[int]) -> None:
    """``period`` (clipping, the two held torques, the substeps, the rotor speeds) equals NumPy around ``integrate``
    (attitude, rate and rotor speeds each within 4 ulps of their largest value: bit for bit where NumPy sums its
    small products in index order, ``tests.numerics``), for both wheel layouts, stuck and switched-off wheels, with
    and without a switch."""
    dyn = _DYNAMICS[layout]
    n = dyn.n_wheels
    qa = np.array(q) if np.linalg.norm(q) > 0.1 else np.array([0.0, 0.0, 0.0, 1.0])
    qa = qa / np.linalg.norm(qa)
    stuck_set = frozenset(i for i in stuck if i < n)
    mode = dyn._mode(stuck_set)
    motor_on = mode.free * np.array([0.0 if o else 1.0 for o in off[:n]])
    wa, ha = np.array(w), np.array(h[:n])
    u_before, u_cmd = np.array(u[:n]), np.array(u[4:4 + n])
    switch_s = min(switch, dt_s)
    expected = _period_in_numpy(dyn, qa, wa, ha, u_before, u_cmd, switch_s, dt_s, motor_on, stuck_set)
    out = np.empty(7 + n)
    attitude_rk4.period(qa, wa, ha, u_before, u_cmd, switch_s, dt_s, motor_on, dyn.max_torque_nm, dyn._max_substep_s,
                        dyn._friction_rate_s, mode.free_axes, mode.gain, mode.i_eff_flat, mode.i_eff_inv_flat,
                        dyn.rotor_inertia_kgm2, dyn.max_momentum_nms, dyn._viscous, dyn._coulomb, 1.0 / dyn._smooth,
                        dyn.wheel_axes_body, mode.free, out)
    for part in (slice(0, 4), slice(4, 7)):
        assert_within_ulps(out[part], expected[part])
    # a still wheel's speed is a small difference of larger terms (seen: 0.0017 rad/s from terms of 0.13, 0.5 ulp of
    # the terms apart)
    assert_within_ulps(out[7:], expected[7:], magnitude=_speed_terms(dyn, expected))
