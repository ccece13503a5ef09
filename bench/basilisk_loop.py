"""Basilisk's closed loop equivalent to the centroid-level flyby, timed: the reference figure of issue 13's speed bench.

Basilisk (AVS Lab, https://hanspeterschaub.info/basilisk) integrates the rigid hub and its reaction wheels
(``spacecraft.Spacecraft`` with a ``reactionWheelStateEffector``, RK4 at the scenario's integration substep, 0.01 s
by default: 100 Hz); a Python PD law runs every control period (0.1 s: 10 Hz) between ``ExecuteSimulation`` calls:
it reads the hub's attitude and rate and the wheel speeds from their output messages, and writes the wheels' torque
command message. The reference attitude is the flyby's, in closed form: the boresight on the line of sight to a
target passing at the scenario's C/A distance and speed (55 km, 7 km/s by default), the plane-normal body axis on
the flyby plane's normal, with the LOS rate and acceleration as the reference rate and feedforward. No images,
no estimation: the loop is given its true state, as a lower bound of what any closed loop costs in Basilisk.

Two steps, so that the Basilisk process need not import this project (Basilisk may live in another interpreter):
    python bench/basilisk_loop.py --print-config [--scenario PATH]          # this project's interpreter
    python bench/basilisk_loop.py --config JSON                             # an interpreter with ``bsk``
or both at once, where one interpreter has both: ``python bench/basilisk_loop.py [--scenario PATH]``.
The second prints one JSON line: wall and processor time of the loop (imports and set-up excluded, as
bench/speed.py's items exclude theirs), the real-time factor, and the final and largest pointing errors after the
first 10 s (deg): a loop that does not track shows there.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from time import perf_counter, process_time  # the benchmark, not the simulator, reads the clock
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "configs" / "scenarios" / "nominal.yaml"
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
# the initial pointing error's axis: the scenario draws one with its seed; a fixed one keeps this process seedless
INITIAL_ERROR_AXIS = (1.0, 1.0, 1.0)
# pointing errors are judged after the initial error has settled (wn = 1.5 rad/s: 4 / (zeta wn) is about 3 s)
SETTLE_S = 10.0


def loop_config(scenario_path: Path) -> dict[str, Any]:
    """The loop's numbers read from a scenario with this project's own loader (run in this project's interpreter)."""
    from scenario.model import load_scenario
    from universe.dynamics import SpacecraftDynamics

    sc = load_scenario(scenario_path)
    u, o = sc.universe, sc.obsw
    s, f = u.spacecraft, u.flyby
    w = s.wheels
    return {
        "duration_s": u.end_s - u.start_s,
        "tau0_s": u.start_s - f.ca_time_s,  # time from C/A at the start
        "ca_distance_m": f.ca_distance_km * 1e3,
        "speed_m_s": f.speed_km_s * 1e3,
        "approach_direction": list(f.approach_direction),
        "ca_direction": list(f.ca_direction),
        "mass_kg": s.mass_kg,
        "inertia_kgm2": [list(r) for r in s.inertia_kgm2],
        "wheel_axes_body": SpacecraftDynamics(s).wheel_axes_body.T.tolist(),  # one row per wheel
        "wheel_inertia_kgm2": w.inertia_kgm2,
        "wheel_max_torque_nm": w.max_torque_nm,
        "wheel_max_momentum_nms": w.max_momentum_nms,
        "wheel_viscous_nms": w.viscous_friction_nms,
        "wheel_coulomb_nm": w.coulomb_friction_nm,
        "substep_s": s.integration_substep_s,
        "control_period_s": o.control_period_s,
        "kp_nm_per_rad": o.control.kp_nm_per_rad,
        "kd_nms_per_rad": o.control.kd_nms_per_rad,
        "boresight_body": list(o.camera.boresight_body),
        "plane_normal_axis_body": list(o.tracking.plane_normal_axis_body),
        "initial_attitude_error_deg": s.initial_attitude_error_deg,
    }


def _unit(v: Any) -> Any:
    import numpy as np

    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _cross(a: Any, b: Any) -> Any:
    """a x b of 3-vectors (numpy's cross costs more than the rest of the control law: it would burden Basilisk)."""
    import numpy as np

    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def run_loop(cfg: dict[str, Any]) -> dict[str, float]:
    """Build the Basilisk simulation of ``cfg``, run its closed loop, return the timings and pointing errors."""
    import numpy as np
    from Basilisk.architecture import messaging
    from Basilisk.simulation import reactionWheelStateEffector, spacecraft
    from Basilisk.utilities import RigidBodyKinematics as rbk
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW

    d, v = float(cfg["ca_distance_m"]), float(cfg["speed_m_s"])
    e_v = _unit(cfg["approach_direction"])
    e_ca = _unit(np.asarray(cfg["ca_direction"], dtype=float) - np.dot(cfg["ca_direction"], e_v) * e_v)
    n = np.cross(e_ca, e_v)  # the flyby plane's normal: the LOS turns about it at d v / r^2
    b = _unit(cfg["boresight_body"])
    p = _unit(np.asarray(cfg["plane_normal_axis_body"], dtype=float) - np.dot(cfg["plane_normal_axis_body"], b) * b)
    triad_t = np.column_stack([b, p, np.cross(b, p)]).T
    inertia = np.asarray(cfg["inertia_kgm2"], dtype=float)
    axes = np.asarray(cfg["wheel_axes_body"], dtype=float)  # (N, 3)
    allocation = np.linalg.pinv(axes.T)  # body torque -> wheel torques (minimum norm)
    kp, kd = float(cfg["kp_nm_per_rad"]), float(cfg["kd_nms_per_rad"])
    u_max = float(cfg["wheel_max_torque_nm"])

    def reference(tau: float) -> tuple[Any, Any, Any]:
        """[NR] (reference axes in inertial), reference rate and acceleration in inertial, at ``tau`` from C/A."""
        r = d * e_ca + v * tau * e_v
        los = -r / np.linalg.norm(r)
        nr = np.column_stack([los, n, _cross(los, n)]) @ triad_t
        r2 = d * d + (v * tau) ** 2
        return nr, (d * v / r2) * n, (-2.0 * d * v ** 3 * tau / (r2 * r2)) * n

    sim = SimulationBaseClass.SimBaseClass()
    dt_ns = macros.sec2nano(float(cfg["substep_s"]))
    sim.CreateNewProcess("dynamics").addTask(sim.CreateNewTask("dynamicsTask", dt_ns))
    hub = spacecraft.Spacecraft()
    hub.ModelTag = "cubesat"
    hub.hub.mHub = float(cfg["mass_kg"])
    hub.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    hub.hub.IHubPntBc_B = inertia.tolist()

    tau0 = float(cfg["tau0_s"])
    nr0, w0_n, _ = reference(tau0)
    # start off the reference by the scenario's initial error, at the reference rate
    angle = math.radians(float(cfg["initial_attitude_error_deg"]))
    error = rbk.PRV2C((angle * _unit(INITIAL_ERROR_AXIS)).tolist())  # [BR]
    bn0 = error @ nr0.T
    hub.hub.sigma_BNInit = [[x] for x in rbk.C2MRP(bn0)]
    hub.hub.omega_BN_BInit = [[x] for x in bn0 @ w0_n]

    factory = simIncludeRW.rwFactory()
    for axis in axes:
        factory.create("custom", axis.tolist(), Js=float(cfg["wheel_inertia_kgm2"]), u_max=u_max,
                       maxMomentum=float(cfg["wheel_max_momentum_nms"]), useRWfriction=True,
                       fCoulomb=float(cfg["wheel_coulomb_nm"]), cViscous=float(cfg["wheel_viscous_nms"]),
                       RWModel=messaging.BalancedWheels)
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    wheels.ModelTag = "wheels"
    factory.addToSpacecraft(wheels.ModelTag, wheels, hub)
    command = messaging.ArrayMotorTorqueMsgPayload()
    command.motorTorque = [0.0] * len(axes)
    command_msg = messaging.ArrayMotorTorqueMsg().write(command)
    wheels.rwMotorCmdInMsg.subscribeTo(command_msg)
    # the effector before the hub, as Basilisk's examples order them
    sim.AddModelToTask("dynamicsTask", wheels, 2)
    sim.AddModelToTask("dynamicsTask", hub, 1)
    sim.InitializeSimulation()

    period_ns = macros.sec2nano(float(cfg["control_period_s"]))
    periods = int(round(float(cfg["duration_s"]) / float(cfg["control_period_s"])))
    n_wheels = len(axes)
    errors_deg = []
    t0, c0 = perf_counter(), process_time()
    for k in range(periods):
        state = hub.scStateOutMsg.read()
        speeds = np.asarray(wheels.rwSpeedOutMsg.read().wheelSpeeds[:n_wheels])
        bn = rbk.MRP2C(state.sigma_BN)
        omega = np.asarray(state.omega_BN_B)
        nr, w_ref_n, a_ref_n = reference(tau0 + k * float(cfg["control_period_s"]))
        br = bn @ nr
        sigma = np.asarray(rbk.C2MRP(br))
        norm = np.linalg.norm(sigma)
        theta = 4.0 * math.atan(norm) / norm * sigma if norm > 0 else sigma  # rotation vector of B from R
        errors_deg.append(math.degrees(math.acos(min(1.0, float((br @ b) @ b)))))
        w_ref = bn @ w_ref_n
        h = inertia @ omega + axes.T @ (float(cfg["wheel_inertia_kgm2"]) * speeds)
        torque = (-kp * theta - kd * (omega - w_ref) + inertia @ (bn @ a_ref_n - _cross(omega, w_ref))
                  + _cross(omega, h))
        # a wheel's motor torque acts on the hub with the opposite sign
        command.motorTorque = np.clip(-(allocation @ torque), -u_max, u_max).tolist()
        command_msg.write(command, sim.TotalSim.CurrentNanos)
        sim.ConfigureStopTime((k + 1) * period_ns)
        sim.ExecuteSimulation()
    wall, cpu = perf_counter() - t0, process_time() - c0
    settled = errors_deg[int(SETTLE_S / float(cfg["control_period_s"])):]
    return {"wall_s": wall, "loop_cpu_s": cpu, "sim_s": float(cfg["duration_s"]), "periods": periods,
            "real_time_factor": float(cfg["duration_s"]) / wall, "final_error_deg": errors_deg[-1],
            "max_error_deg": max(settled)}


def main() -> None:
    """Print the loop's configuration (``--print-config``) or run the loop and print its figures, one JSON line."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", type=Path, default=SCENARIO)
    p.add_argument("--print-config", action="store_true", help="print the loop's configuration read from --scenario")
    p.add_argument("--config", help="the loop's configuration as JSON (from --print-config); --scenario is not read")
    args = p.parse_args()
    if args.print_config:
        print(json.dumps(loop_config(args.scenario)))
        return
    cfg = json.loads(args.config) if args.config else loop_config(args.scenario)
    print(json.dumps(run_loop(cfg)))


if __name__ == "__main__":
    sys.exit(main())
