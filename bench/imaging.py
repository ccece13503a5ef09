"""Benchmark of the imaging subsystem on independent frames, against the truth and the OpenCV pipeline, and its speed.

Run: .venv/bin/python bench/imaging.py [--frames N] [--timing-frames M] [--repeats R] [--seed S] [--jobs J]
     [--reference-code DIR [--rounds K]]

Independent frames: ``tests/obsw/frame_generator.py`` (written for the tests, sharing nothing with the universe's
camera: triaxial bodies, four shading laws, phase 20-120 deg, Didymos 1-400 px across, plume in 40 % of the frames,
stars, bias, shot and read noise, saturated hot pixels, cosmic-ray streaks, dead pixels and columns, bodies off the
edge). Each frame is processed with the prediction the flight software would have (``tests/obsw/imaging_trials.py``)
and the bad-pixel map ground would upload (dead pixels and columns, half the hot pixels), and by the OpenCV pipeline
(``tests/obsw/opencv_reference.py``) with the same map. Printed:

- detection: bodies whose lit part spans at least 3 binned px, not hidden by the other body, at least half in
  the frame and detectable (the peak of the body's noise-free binned signal at least 10 sigma of the binned
  background noise: 5 sigma to the threshold and 5 more of noise) and not swallowed by the other body (the smaller
  of a pair whose noise-free images, cut at 5 sigma, touch or overlap: seen against the other's lit surface or limb,
  one blob at the noise floor, with no edge between them at the same albedo; ``imaging_trials.visible``; counted
  apart), reported as
  themselves (a reported region is the body whose pixels it holds most of, ``imaging_trials.identity``);
- misses and wrong reports (a body reported where another body, a star, a defect or the plume is; counted for
  bodies of 3 px and more), each with its classes (``imaging_trials.failure_classes``: small, faint, phase, edge,
  close pair, plume, unrecognised trajectory; and what was reported instead);
- every report of a body of any size not cut by the frame's edge: the share on the body it was taken for and within
  the paper's 15 px of its centre; the share within 15 px of the true centre of the body it is reported as, whatever
  the region holds most of (the paper's criterion: a sub-pixel pair or a body in its glow counts by its centre), each
  report beyond listed; and the point-like Didymos identified but not reported, as likely a star as Didymos
  (``ImagingConfig.didymos_min_report_probability``);
- one defect more (a saturated hot pixel or a 6 px cosmic ray on Didymos, on Dimorphos, or anywhere; same noise):
  reports whose body changed to another blob, and bodies found or lost, each listed, those of bodies the chain must
  find (as for detection) counted apart;
- centroids: distance from the OpenCV region centroid of the same blob; distance from the true centre of correctly
  reported bodies not cut by the frame's edge, before and after the phase correction.

Speed: the flight code and the OpenCV pipeline (``opencv_pipeline``: the same defect handling, binning, threshold and
labelling in OpenCV's fast primitives, equal to the reference's result) timed interleaved on the same 1024x1024
frames, each repeated: frames of the universe camera along the flyby (default
detector, plume) and independent frames; the median and the best (least disturbed by other processes) are printed.
With ``--reference-code DIR`` (another build, e.g. ``git archive 849cbec | tar -x -C DIR``), the same timing runs
in two child processes side by side, one per build, on the same frames (so a slow spell of this shared machine hits
both alike), in ``--rounds`` rounds: each build's median and this build's over the reference's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from itertools import repeat
from pathlib import Path
from time import perf_counter

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parent.parent
# run as a script, bench/ leads sys.path and bench/universe.py would shadow the universe package
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

from obsw.config import CameraKnowledge, ImagingConfig, TargetKnowledge  # noqa: E402
from obsw.imaging import BadPixelMap, Detections, predict_frame, process_frame  # noqa: E402
from obsw.imaging_kernels import warm_up  # noqa: E402
from obsw.trajectory import NominalTrajectory  # noqa: E402
from tests.obsw.frame_generator import random_scene, render  # noqa: E402
from tests.obsw.imaging_trials import (  # noqa: E402
    CFG,
    PAPER_LIMIT_PX,
    failure_classes,
    ground_map,
    peak_snr,
    perturbed_identities,
    prediction_for,
    run_trial,
    visible,
)
from tests.obsw.opencv_reference import OpenCvMap, opencv_pipeline  # noqa: E402
from universe.camera import Body, Scene, render_frame  # noqa: E402
from universe.config import UniverseConfig  # noqa: E402
from universe.geometry import FlybyGeometry  # noqa: E402
from universe.shapes import ShapeModel  # noqa: E402

DEFECTS = (("hot", 0), ("hot", 1), ("hot", None), ("cosmic", 0), ("cosmic", 1), ("cosmic", None))


NAMES = ("Didymos", "Dimorphos")


@dataclass
class Tally:
    """The trials' figures over some frames; ``merge`` adds another's (lines kept in frame order)."""

    found: list[list[int]] = field(default_factory=lambda: [[0, 0], [0, 0]])  # per body: must be found, found
    swallowed_found: list[list[int]] = field(default_factory=lambda: [[0, 0], [0, 0]])
    misses: list[str] = field(default_factory=list)
    wrong: list[str] = field(default_factory=list)
    wrong_small: int = 0
    reports: int = 0  # bodies reported (either body, any size), not cut by the frame's edge
    reports_right: int = 0  # of them, on the body they were taken for and within the paper's 15 px of its centre
    reports_near: int = 0  # of them, within 15 px of the true centre of the body they are reported as, whatever blob
    far_reports: list[str] = field(default_factory=list)  # the others
    withheld: int = 0  # point-like Didymos identified but not reported: as likely a star (didymos_probability)
    opencv: list[float] = field(default_factory=list)
    errors: list[list[tuple[float, float]]] = field(default_factory=lambda: [[], []])
    far: list[str] = field(default_factory=list)
    changed: list[str] = field(default_factory=list)
    changed_must: int = 0  # of bodies the chain must find (``visible``): at least 3 px, bright, apart
    lost_found: list[str] = field(default_factory=list)
    lost_found_must: int = 0  # of bodies the chain must find
    trials: int = 0

    def merge(self, other: Tally) -> None:
        """Add ``other``'s figures (of later frames) to these."""
        for i in (0, 1):
            for j in (0, 1):
                self.found[i][j] += other.found[i][j]
                self.swallowed_found[i][j] += other.swallowed_found[i][j]
            self.errors[i] += other.errors[i]
        for name in ("misses", "wrong", "opencv", "far", "far_reports", "changed", "lost_found"):
            getattr(self, name).extend(getattr(other, name))
        for name in ("wrong_small", "reports", "reports_right", "reports_near", "withheld", "changed_must",
                     "lost_found_must", "trials"):
            setattr(self, name, getattr(self, name) + getattr(other, name))


def frame_tally(seed: int, k: int, defects: bool) -> Tally:
    """The trials of independent frame ``k`` of ``seed`` (its scene, noise and defects fixed by both alone)."""
    out = Tally()
    rng = np.random.default_rng([seed, k])
    scene = random_scene(rng)
    prediction = prediction_for(scene, rng, 3.0 if rng.random() < 0.5 else 30.0)
    t = run_trial(scene, k, prediction)
    base = (t.didymos.truth_index, t.dimorphos.truth_index)
    for i, body in ((0, t.didymos), (1, t.dimorphos)):
        size = t.frame.truth[i].diameter_512_px
        line = (f"frame {k}: {NAMES[i]} ({size:.1f} px, SNR {peak_snr(t.frame, i):.0f}): "
                f"{', '.join(failure_classes(t, i))}")
        if visible(t.frame, i, require_apart=False) and not visible(t.frame, i):
            out.swallowed_found[i][0] += 1
            out.swallowed_found[i][1] += body.truth_index == i
        if visible(t.frame, i):
            out.found[i][0] += 1
            out.found[i][1] += body.truth_index == i
            if body.truth_index != i:
                out.misses.append(line)
        if body.truth_index is not None and body.truth_index != i:
            if visible(t.frame, i, require_snr=False, require_apart=False):
                out.wrong.append(line)
            else:
                out.wrong_small += 1
        if body.opencv_px is not None:
            out.opencv.append(body.opencv_px)
        blob = t.detections.didymos if i == 0 else t.detections.dimorphos
        if blob is not None and not blob.touches_edge:  # a body cut by the edge: its centre may be off the image
            out.reports += 1
            out.reports_right += body.truth_index == i and body.error_px is not None \
                and body.error_px <= PAPER_LIMIT_PX
            # the paper's criterion: the reported centre against the true centre of the body it is reported as
            off = math.dist(blob.centroid_col_row, t.frame.truth[i].centre_512)
            if off <= PAPER_LIMIT_PX:
                out.reports_near += 1
            else:
                out.far_reports.append(f"frame {k}: {NAMES[i]} ({size:.1f} px) reported {off:.1f} px from its centre: "
                                       f"{', '.join(failure_classes(t, i))}")
        elif i == 0:
            out.withheld += t.detections.didymos_probability < CFG.didymos_min_report_probability
        if body.truth_index == i and blob is not None and not blob.touches_edge:
            out.errors[i].append((body.uncorrected_error_px, body.error_px))  # type: ignore[arg-type]
            if body.error_px > PAPER_LIMIT_PX:  # type: ignore[operator]
                out.far.append(f"frame {k}: {NAMES[i]} {body.error_px:.1f} px from its centre: "
                               f"{', '.join(c for c in failure_classes(t, i) if not c.startswith('reported'))}")
    if not defects:
        return out
    for kind, target in DEFECTS:
        got = perturbed_identities(scene, k, prediction, kind, target, np.random.default_rng([seed, k, 7]))
        out.trials += 1
        for i in (0, 1):
            if got[i] == base[i]:
                continue
            must = visible(t.frame, i)
            size = t.frame.truth[i].diameter_512_px
            line = (f"frame {k}: {kind} on {target}: {NAMES[i]} ({size:.2f} px"
                    f"{'' if must else ', not one the chain must find'}) {base[i]} -> {got[i]}")
            if got[i] is not None and base[i] is not None:
                out.changed_must += must
                out.changed.append(line)
            else:
                out.lost_found_must += must
                out.lost_found.append(line)
    return out


def _tallies(n: int, seed: int, defects: bool, jobs: int) -> Iterator[Tally]:
    """Each frame's tally in frame order, computed in ``jobs`` processes."""
    if jobs <= 1:
        yield from (frame_tally(seed, k, defects) for k in range(n))
        return
    with ProcessPoolExecutor(max_workers=jobs, initializer=warm_up) as pool:
        yield from pool.map(frame_tally, repeat(seed), range(n), repeat(defects))


def independent(n: int, seed: int, defects: bool = True, jobs: int = 1) -> None:
    """Run the trials on n independent frames and print the figures, each miss and wrong report with its classes;
    progress on stderr. The figures are the same for any ``jobs``."""
    total = Tally()
    t0 = perf_counter()
    for k, tally in enumerate(_tallies(n, seed, defects, jobs), start=1):
        total.merge(tally)
        if k % 10 == 0 or k == n:
            left = (perf_counter() - t0) / k * (n - k)
            print(f"\r  frames {k}/{n}, about {left:.0f} s left ", end="\n" if k == n else "", file=sys.stderr,
                  flush=True)
    _print_tally(total, n, seed, defects)


def _print_tally(t: Tally, n: int, seed: int, defects: bool) -> None:
    print(f"Independent frames: {n} (tests/obsw/frame_generator.py, seed {seed})")
    for i, name in enumerate(NAMES):
        total, ok = t.found[i]
        print(f"  {name} detected in {ok} of {total} frames where it must be ({100.0 * ok / max(total, 1):.1f} %)")
        total, ok = t.swallowed_found[i]
        if total:
            print(f"    and in {ok} of {total} frames where the other body swallows it (not required)")
    print(f"  misses: {len(t.misses)}")
    for line in t.misses:
        print(f"    {line}")
    print(f"  wrong reports of bodies of 3 px and more: {len(t.wrong)} (on another body, a star, a defect or the "
          f"plume); of smaller bodies: {t.wrong_small}")
    for line in t.wrong:
        print(f"    {line}")
    print(f"  reports not at the edge on the body taken for, within 15 px of its centre: {t.reports_right} of "
          f"{t.reports} ({100.0 * t.reports_right / max(t.reports, 1):.2f} %); point-like Didymos not reported, as "
          f"likely a star (probability under {CFG.didymos_min_report_probability}): {t.withheld}")
    print(f"  reports not at the edge within 15 px of the true centre of the body they are reported as, whatever the "
          f"region holds most of (the paper's criterion): {t.reports_near} of {t.reports} "
          f"({100.0 * t.reports_near / max(t.reports, 1):.2f} %)")
    for line in t.far_reports:
        print(f"    {line}")
    if defects:
        print(f"  one defect more, {t.trials} trials x 2 bodies: {len(t.changed)} reports changed to another blob "
              f"({t.changed_must} of bodies the chain must find, {len(t.changed) - t.changed_must} of smaller or "
              f"fainter ones), {len(t.lost_found)} found or lost ({t.lost_found_must} of bodies the chain must find)")
        for line in t.changed + t.lost_found:
            print(f"    {line}")
    beyond = sum(1 for d in t.opencv if d > 2.0)
    print(f"  centroid vs the OpenCV region centroid of the same blob: {len(t.opencv)} reports, max "
          f"{max(t.opencv):.2e} px, {beyond} beyond 2 px, {sum(1 for d in t.opencv if d > 15.0)} beyond 15 px")
    for i, name in enumerate(NAMES):
        if not t.errors[i]:
            continue
        before = np.array([e[0] for e in t.errors[i]])
        after = np.array([e[1] for e in t.errors[i]])
        print(f"  {name} centre vs truth ({len(after)} reports, not at the edge): phase-corrected median "
              f"{np.median(after):.2f} px, 99th pct {np.percentile(after, 99):.2f}, max {after.max():.2f}, "
              f"{int((after > PAPER_LIMIT_PX).sum())} beyond 15 px; uncorrected median {np.median(before):.2f}, max "
              f"{before.max():.2f}")
    for line in t.far:
        print(f"    {line}")


SHAPES = (ShapeModel(seed=1), ShapeModel(seed=2, axis_ratios=(1.3, 1.0, 0.85)))


def flyby_frames(n: int, seed: int) -> list[tuple[np.ndarray, object]]:
    """n frames of the universe camera (default detector, plume) from t = 50 s (Dimorphos 2 px) to C/A, pointed at
    Dimorphos with 1 mrad jitter, each with the flight software's prediction."""
    uc = UniverseConfig()
    geo = FlybyGeometry(uc.flyby, uc.bodies)
    rng = np.random.default_rng(seed)
    f = uc.flyby
    traj = NominalTrajectory(ca_time_obt_s=f.ca_time_s, ca_distance_km=f.ca_distance_km, speed_km_s=f.speed_km_s,
                             approach_direction=f.approach_direction, ca_direction=f.ca_direction)
    targets = TargetKnowledge(sun_direction_inertial=uc.bodies.sun_direction)
    out = []
    for t in np.linspace(50.0, 165.0, n):
        sc = geo.spacecraft_position_m(t)
        did, dim = geo.didymos_position_m(t), geo.dimorphos_position_m(t)
        z = (dim - sc) / np.linalg.norm(dim - sc)
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        q = Rotation.from_rotvec(rng.normal(0.0, 1e-3, 3)) * Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z]))
        scene = Scene(camera_position_m=sc, q_body_to_inertial=q.as_quat(), body_rate_rad_s=np.zeros(3),
                      exposure_s=uc.camera.exposure_s, bodies=(Body(did, 390.0, SHAPES[0]), Body(dim, 82.0, SHAPES[1])),
                      sun_direction=geo.sun_direction(), time_since_impact_s=float(t), star_seed=3,
                      camera_velocity_m_s=geo.spacecraft_velocity_m_s(t), plume_body_index=1)
        frame = render_frame(scene, uc.camera, uc.plume, rng)
        out.append((frame, predict_frame(q.as_quat(), targets, CameraKnowledge(), ImagingConfig(), traj, float(t))))
    return out


TimedFrame = tuple[np.ndarray, object, BadPixelMap | None, OpenCvMap | None]  # frame, prediction, both maps


def timing(label: str, frames: list[TimedFrame], repeats: int, threads: int) -> None:
    """Time process_frame and the OpenCV pipeline interleaved on the same frames; print medians, best and ratio."""
    cfg = ImagingConfig()
    ours: list[float] = []
    ref: list[float] = []
    previous: Detections | None = None
    for frame, prediction, bad, cv_map in frames:
        process_frame(frame, cfg, previous, prediction=prediction, bad_pixels=bad)  # warm caches for this frame
        opencv_pipeline(frame, cv_map)
        for _ in range(repeats):
            t0 = perf_counter()
            det = process_frame(frame, cfg, previous, prediction=prediction, bad_pixels=bad)
            t1 = perf_counter()
            opencv_pipeline(frame, cv_map)
            t2 = perf_counter()
            ours.append(t1 - t0)
            ref.append(t2 - t1)
        previous = det
    m_ours, m_ref = statistics.median(ours) * 1e3, statistics.median(ref) * 1e3
    b_ours, b_ref = min(ours) * 1e3, min(ref) * 1e3
    p90 = float(np.percentile(ours, 90)) * 1e3
    print(f"Speed, {label}: {len(frames)} frames x {repeats} runs, 1024x1024 12-bit")
    print(f"  process_frame:                median {m_ours:.3f} ms/frame (best {b_ours:.3f}, 90th pct {p90:.3f})")
    print(f"  OpenCV pipeline ({threads} thread{'s' if threads > 1 else ''}): median {m_ref:.3f} ms/frame "
          f"(best {b_ref:.3f})")
    print(f"  ratio ours / OpenCV:          {m_ours / m_ref:.2f} (best {b_ours / b_ref:.2f})")


# one build's timing in a child process: the frame sets from a pickle, process_frame timed after OpenCV's pipeline
# as ``timing`` does; prints {set label: [seconds, ...]} as one JSON line
_TIMING_CHILD = r"""
import json, pickle, sys
from time import perf_counter
import cv2
path, repeats, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
cv2.setNumThreads(threads)
from obsw.config import ImagingConfig
from obsw.imaging import process_frame
from obsw.imaging_kernels import warm_up
from tests.obsw.opencv_reference import opencv_pipeline
warm_up()
with open(path, "rb") as f:
    sets = pickle.load(f)
cfg = ImagingConfig()
out = {}
for label, frames in sets:
    times, previous = [], None
    for frame, prediction, bad, cv_map in frames:
        det = process_frame(frame, cfg, previous, prediction=prediction, bad_pixels=bad)
        opencv_pipeline(frame, cv_map)
        for _ in range(repeats):
            t0 = perf_counter()
            det = process_frame(frame, cfg, previous, prediction=prediction, bad_pixels=bad)
            times.append(perf_counter() - t0)
            opencv_pipeline(frame, cv_map)
        previous = det
    out[label] = times
print(json.dumps(out))
"""


def side_by_side(sets: list[tuple[str, list[TimedFrame]]], reference: Path, repeats: int, rounds: int,
                 threads: int) -> None:
    """Time this build's process_frame and the reference build's in two child processes run at once, on the same
    frames, ``rounds`` times; print each build's median per round and over all rounds, and their ratio."""
    if not (reference / "obsw" / "imaging.py").is_file():
        sys.exit(f"--reference-code {reference}: no obsw/imaging.py there (give the root of another build)")
    pooled: dict[str, dict[str, list[float]]] = {"this": {}, "reference": {}}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.pkl"
        with path.open("wb") as f:
            pickle.dump(sets, f)
        for k in range(rounds):
            procs = {name: subprocess.Popen(
                [sys.executable, "-c", _TIMING_CHILD, str(path), str(repeats), str(threads)],
                env=dict(os.environ, PYTHONPATH=str(code)), cwd=code, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                text=True) for name, code in (("this", ROOT), ("reference", reference.resolve()))}
            for name, p in procs.items():
                out, err = p.communicate()
                if p.returncode != 0:
                    for other in procs.values():  # no child left running behind the error
                        other.kill()
                    sys.exit(f"the {name} build's timing failed:\n{err.strip()[-2000:]}")
                for label, times in json.loads(out.strip().splitlines()[-1]).items():
                    pooled[name].setdefault(label, []).extend(times)
                    if name == "reference":
                        mine = statistics.median(pooled["this"][label][-len(times):]) * 1e3
                        ref = statistics.median(times) * 1e3
                        print(f"  round {k + 1}, {label}: this build {mine:.3f} ms, reference {ref:.3f} ms, "
                              f"ratio {mine / ref:.2f}")
    print(f"Side by side with {reference} ({rounds} rounds x {repeats} runs per frame, two processes at once):")
    for label in pooled["this"]:
        mine = statistics.median(pooled["this"][label]) * 1e3
        ref = statistics.median(pooled["reference"][label]) * 1e3
        print(f"  {label}: process_frame median {mine:.3f} ms, reference {ref:.3f} ms, ratio {mine / ref:.2f}")


def main() -> None:
    """Run the independent-frame trials, then the timing."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=310, help="independent frames for the trials")
    parser.add_argument("--timing-frames", type=int, default=40, help="frames of each set for the timing")
    parser.add_argument("--repeats", type=int, default=15, help="timed runs per frame and pipeline")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=1,
                        help="processes for the independent-frame trials (the figures are the same for any number)")
    parser.add_argument("--no-defect-trials", action="store_true",
                        help="skip the one-defect-more trials (six more frames per frame)")
    parser.add_argument("--opencv-threads", type=int, default=1,
                        help="OpenCV worker threads (1: like the single-threaded flight code)")
    parser.add_argument("--reference-code", type=Path,
                        help="another build's root: time it side by side with this one instead of alone")
    parser.add_argument("--rounds", type=int, default=3, help="side-by-side rounds (with --reference-code)")
    args = parser.parse_args()
    cv2.setNumThreads(args.opencv_threads)
    warm_up()
    if args.frames:
        independent(args.frames, args.seed, not args.no_defect_trials, args.jobs)
    if not args.timing_frames:
        return
    flyby: list[TimedFrame] = [(frame, pred, None, None) for frame, pred in flyby_frames(args.timing_frames,
                                                                                         args.seed)]
    generated: list[TimedFrame] = []
    for k in range(args.timing_frames):
        rng = np.random.default_rng([args.seed, 10_000 + k])
        scene = random_scene(rng)
        d = scene.defects
        pixels = [(c, r) for c, r, _ in d.hot[: len(d.hot) // 2]] + list(d.dead)
        generated.append((render(scene, rng).pixels, prediction_for(scene, rng, 3.0), ground_map(scene),
                          OpenCvMap.of(scene.size_px, pixels, d.dead_columns)))
    sets = [("universe camera along the flyby", flyby), ("independent frames, bad-pixel map applied", generated)]
    if args.reference_code is not None:
        side_by_side(sets, args.reference_code, args.repeats, args.rounds, args.opencv_threads)
        return
    for label, frames in sets:
        timing(label, frames, args.repeats, args.opencv_threads)


if __name__ == "__main__":
    main()
