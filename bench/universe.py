"""Benchmark of the universe: frame render time, dynamics steps per second, real-time factor of a whole flyby.

Run: ``.venv/bin/python bench/universe.py [--frames 30] [--dyn-steps 3000] [--rounds 5] [--scenario PATH]``

1. Median time to render one 1024x1024 frame of the scenario's universe (``scene.render_at``: scene, bodies,
   plume, stars, noise, true target pixels) with perfect pointing (``universe.render``) at three geometries:
   far (Didymos ~10 px), mid (~60 px) and C/A (~290 px); one core (single-thread OpenCV, BLAS and Numba). Target:
   15 ms. The reference, timed in blocks alternating with the renders', is drawing one 1024x1024 float32 frame of
   standard normals with numpy; the median of the blocks' ratios says how many plain noise frames a rendered frame
   costs on this machine, whatever else the machine is doing. This shared machine has slow spells (the reference
   then takes up to 1.6x its usual time), so the ratios are also applied to the run's fastest reference block: the
   render times of the machine at its own best speed in the same run.
2. ``SpacecraftDynamics.step`` at dt = 0.1 s (default spacecraft, three wheels): median steps per second over
   rounds, and the real-time factor that alone allows.
3. The universe alone over the scenario's run (420 s for the nominal flyby): ``Universe.advance`` at the control
   period with zero torques, a frame requested every 1 s, ``ground_step`` when due; real-time factor with frames
   and, as the reference in the same run, without any frame. With zero torques the target drifts out of the field
   within seconds, so most of these frames show only stars and noise; the per-geometry render times of part 1 are
   the cost of frames with the asteroids in them.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the render budget is stated
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from time import perf_counter  # noqa: E402  (the benchmark, not the simulator, reads the clock)

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contracts.messages import FrameRequest, StepReply  # noqa: E402
from scenario.model import Scenario, load_scenario  # noqa: E402
from universe.camera import focal_length_px  # noqa: E402
from universe.dynamics import AttitudeState, SpacecraftDynamics  # noqa: E402
from universe.render import PerfectPointingCamera  # noqa: E402
from universe.scene import render_at  # noqa: E402
from scenario import compose

RENDER_TARGET_MS = 15.0  # issue 3: at most 15 ms per 1024x1024 frame on one core
BLOCK = 5  # renders (and reference frames) timed back to back


def time_for_didymos_size_s(scenario: Scenario, size_px: float) -> float:
    """True time before C/A at which Didymos spans ``size_px`` pixels (C/A itself if it never gets that big)."""
    u = scenario.universe
    f = focal_length_px(u.camera)
    range_m = u.bodies.didymos_diameter_m * f / size_px
    b = u.flyby.ca_distance_km * 1e3
    along = math.sqrt(max(range_m * range_m - b * b, 0.0))
    return u.flyby.ca_time_s - along / (u.flyby.speed_km_s * 1e3)


def render_medians_ms(scenario: Scenario, frames: int) -> list[tuple[str, float, float, float, float, float, float]]:
    """(name, time s, Didymos size px, median render ms, median reference ms, median ratio, best reference block
    median ms) per geometry.

    Renders and reference frames (numpy normal deviates) alternate in blocks of ``BLOCK`` (each kind back to back,
    as a run renders frames); the ratio of each pair of blocks' medians cancels the slow and fast spells of a shared
    machine, and the median of those ratios is reported."""
    u = scenario.universe
    cam = PerfectPointingCamera(compose.universe(scenario))
    rng = np.random.default_rng(0)
    out = []
    f = focal_length_px(u.camera)
    for name, size in (("far", 10.0), ("mid", 60.0), ("C/A", None)):
        t = u.flyby.ca_time_s if size is None else time_for_didymos_size_s(scenario, size)
        cam.frame_at(t)  # aim the universe at this geometry; warms the shape tables, star cells and kernels
        times, refs, ratios, ref_blocks = [], [], [], []
        for _ in range(max(1, frames // BLOCK)):
            block_ref, block = [], []
            for _ in range(BLOCK):
                t0 = perf_counter()
                rng.standard_normal((u.camera.resolution_px,) * 2, dtype=np.float32)
                block_ref.append(perf_counter() - t0)
            for _ in range(BLOCK):
                t0 = perf_counter()
                render_at(cam.universe, u.camera.exposure_s)
                block.append(perf_counter() - t0)
            times += block
            refs += block_ref
            ratios.append(statistics.median(block) / statistics.median(block_ref))
            ref_blocks.append(statistics.median(block_ref))
        g = cam.universe.geometry
        rng_m = float(np.linalg.norm(g.didymos_position_m(t) - g.spacecraft_position_m(t)))
        ratio = statistics.median(ratios)
        out.append((name, t, u.bodies.didymos_diameter_m / rng_m * f, statistics.median(times) * 1e3,
                    statistics.median(refs) * 1e3, ratio, min(ref_blocks) * 1e3))
    return out


def dynamics_steps_per_s(scenario: Scenario, steps: int, rounds: int) -> float:
    """Median over ``rounds`` of SpacecraftDynamics.step calls per second at dt = 0.1 s with changing torques."""
    dyn = SpacecraftDynamics(scenario.universe.spacecraft)
    n = dyn.n_wheels
    torques = [np.full(n, 0.003 * math.sin(0.01 * k)) for k in range(steps)]
    rates = []
    for _ in range(rounds):
        state = AttitudeState(q=np.array([0.0, 0.0, 0.0, 1.0]), omega_rad_s=np.array([1e-3, -2e-3, 5e-4]),
                              wheel_speed_rad_s=np.zeros(n))
        t0 = perf_counter()
        for tq in torques:
            state = dyn.step(state, tq, 0.1)
        rates.append(steps / (perf_counter() - t0))
    return statistics.median(rates)


def universe_run(scenario: Scenario, frame_every: int | None) -> tuple[float, float, int, int]:
    """Drive the universe over its whole run; (simulated s, wall s, frames, frames with Dimorphos in the field).

    ``frame_every``: request a frame every that many control periods (None: never)."""
    from universe.simulator import Universe

    u = compose.universe(scenario)
    n = u.dynamics.n_wheels
    zero = (0.0,) * n
    t0 = perf_counter()
    u.begin()
    k = 0
    in_view = 0
    while True:
        if u.ground_due():
            gs = u.ground_step()
            in_view += sum(1 for r in gs.truth if r.frame_id is not None and r.target_in_fov)
        frame = frame_every is not None and k % frame_every == 0
        nxt = u.advance(StepReply(step=k, wheel_torque_nm=zero,
                                  frame_request=FrameRequest(exposure_s=scenario.universe.camera.exposure_s)
                                  if frame else None))
        k += 1
        if nxt is None:
            break
    wall = perf_counter() - t0
    while (gs := u.drain()) is not None:  # the last truth records, after the clock stopped
        in_view += sum(1 for r in gs.truth if r.frame_id is not None and r.target_in_fov)
    return u.t_s - scenario.universe.start_s, wall, u.frame_count, in_view


def main() -> None:
    """Measure and print every figure."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", type=Path, default=ROOT / "configs" / "scenarios" / "nominal.yaml")
    ap.add_argument("--frames", type=int, default=30, help="timed renders per geometry")
    ap.add_argument("--dyn-steps", type=int, default=3000, help="dynamics steps per round")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of dynamics steps")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    scenario = load_scenario(args.scenario)
    u = scenario.universe
    print(f"universe benchmark: {scenario.name}, {u.camera.resolution_px}x{u.camera.resolution_px} frames, "
          f"one thread (cv2.setNumThreads(1), OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']})")

    print(f"\n1. render one frame (render_at, perfect pointing), median of {args.frames}, in blocks of {BLOCK} alternating "
          "with\n   the reference (drawing a 1024x1024 float32 frame of normal deviates with numpy):")
    rows = render_medians_ms(scenario, args.frames)
    for name, t, size, ms, ref_ms, ratio, _ in rows:
        verdict = "within" if ms <= RENDER_TARGET_MS else "over"
        print(f"   {name:5s} t={t:+7.1f} s  Didymos {size:5.0f} px  {ms:7.2f} ms  (reference {ref_ms:6.2f} ms, "
              f"ratio {ratio:4.2f})  {verdict} the {RENDER_TARGET_MS:g} ms target")
    quiet_ms = min(r[6] for r in rows)
    print(f"   the machine at its fastest in this run (best reference block {quiet_ms:.2f} ms), ratio x that:")
    for name, _, _, _, _, ratio, _ in rows:
        ms = ratio * quiet_ms
        verdict = "within" if ms <= RENDER_TARGET_MS else "over"
        print(f"   {name:5s} {ms:7.2f} ms  {verdict} the {RENDER_TARGET_MS:g} ms target")

    rate = dynamics_steps_per_s(scenario, args.dyn_steps, args.rounds)
    print(f"\n2. SpacecraftDynamics.step at dt 0.1 s: {rate:,.0f} steps/s (median of {args.rounds} x {args.dyn_steps}); "
          f"real-time factor {rate * 0.1:,.0f}")

    period = max(1, round(u.camera.frame_period_s / u.control_period_s))
    sim_s, wall_s, frames, in_view = universe_run(scenario, period)
    sim0_s, wall0_s, _, _ = universe_run(scenario, None)
    print(f"\n3. universe alone over {sim_s:.0f} s at {1 / u.control_period_s:g} Hz, zero torques:")
    print(f"   frames every {period * u.control_period_s:g} s: {wall_s:6.2f} s wall, real-time factor "
          f"{sim_s / wall_s:6.1f} ({frames} frames, {in_view} with Dimorphos in the field)")
    print(f"   reference, no frames:    {wall0_s:6.2f} s wall, real-time factor {sim0_s / wall0_s:6.1f}  "
          f"(frames take {100 * (1 - wall0_s / wall_s):.0f} % of the run)")


if __name__ == "__main__":
    main()
