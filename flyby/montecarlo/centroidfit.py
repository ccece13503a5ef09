"""``flyby mc-fit``: fit the centroid-level measurement model (``universe.centroid_model``) on image-level runs.

Each image-level run gives, per camera frame, the truth (the pinhole projections of both bodies' centres, the
attitude, ranges, phase angle) and what the on-board imaging chain reported (the NavigationReport's binned
centroids, taken back to full resolution). Over all frames of all runs:

- a reported Dimorphos farther from its truth than the report's centroid tolerance is misidentified; consecutive
  ones (among the frames of a run reporting it) make an episode: the start rate is per frame reporting Dimorphos
  outside an episode, with the episodes' mean length;
- a frame with Dimorphos in the image reports it with probability (1 - merge) x (1 - dropout), merge depending
  on the gap between the two discs (4 px bins) and dropout on the phase angle (10 deg bins): both tables are
  estimated alternately, each bin's seen fraction divided by what the other table expects;
- per phase bin, the least-squares centroid shift towards the Sun's side per apparent radius;
- the noise left after that bias, per axis, as a + b x radius (non-negative least squares over radius bins of a
  robust sigma, 1.4826 x the median absolute residual);
- Didymos's dropout rate over the frames with Didymos in the image.

The model file written (``universe: centroid_model: ...``) is what ``flyby mc --centroid-model FILE`` takes. Each
run's samples are kept (``--samples DIR``, default beside the model file), so an interrupted fit resumes and a
change to the fit reruns no flyby.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.optimize import nnls

from analysis.telemetry import received_telemetry
from contracts import pus
from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CONFIG, EXIT_OK
from contracts.messages import TruthRecord
from flyby.inprocess import run_in_process
from flyby.montecarlo.campaign import build_campaign, campaign_of
from scenario.dispersions import dispersed_run
from scenario.model import Scenario
from universe.camera import Body, Scene
from universe.config import CentroidModelConfig
from universe.measurement import body_view

PHASE_BIN_DEG = 10.0
GAP_BIN_PX = 4.0  # full-resolution px
GAP_RANGE_PX = (-40.0, 80.0)  # gaps beyond fall in the end bins
ALTERNATIONS = 10  # alternating estimates of the merge and dropout tables (they settle in a few)
NEVER_MERGED_PX = 40.0  # discs this far apart are always told apart (the chain's blobs are a few px wide)
MIN_BIN_FRAMES = 30  # a phase bin enters the tables with at least this many frames
MIN_BIAS_FRAMES = 10  # and its bias with at least this many well-identified detections (else interpolated)
MIN_GAP_FRAMES = 10  # a gap bin enters the merge table with at least this many frames (the few with the discs
#                      touching, around C/A, are what the table is for)
RADIUS_BINS = 10
MAD_TO_SIGMA = 1.4826  # one Gaussian sigma per median absolute deviation


@dataclass
class FrameSamples:
    """Per camera frame of image-level runs: truth and report, full-resolution px (NaN where absent)."""

    true_dim: NDArray[np.float64]  # (N, 2)
    true_did: NDArray[np.float64]
    reported_dim: NDArray[np.float64]
    reported_did: NDArray[np.float64]
    radius_dim: NDArray[np.float64]
    radius_did: NDArray[np.float64]
    phase_dim_deg: NDArray[np.float64]
    towards_sun_dim: NDArray[np.float64]  # (N, 2) unit image direction
    run: NDArray[np.int64]  # the run each frame belongs to (frames of a run in time order)
    side_px: int

    @classmethod
    def concat(cls, parts: list[FrameSamples]) -> FrameSamples:
        """All frames of several runs."""
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in (
            "true_dim", "true_did", "reported_dim", "reported_did", "radius_dim", "radius_did", "phase_dim_deg",
            "towards_sun_dim", "run")), side_px=parts[0].side_px)

    def save(self, path: Path) -> None:
        """Write the samples as one .npz file, whole or not at all (written aside, then renamed)."""
        tmp = path.with_name(path.name + ".part")
        with open(tmp, "wb") as f:
            np.savez(f, **{k: np.asarray(v) for k, v in vars(self).items()})
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> FrameSamples:
        """Samples written by ``save``."""
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        return cls(**{**d, "side_px": int(d["side_px"])})

    def inside(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether positions fall in the frame (as the measurement model decides it)."""
        return np.all(np.isfinite(xy) & (xy >= -0.5) & (xy <= self.side_px - 0.5), axis=1)


def full_resolution(xy: tuple[float, float] | None, factor: float) -> tuple[float, float]:
    """A binned position back at full resolution: the inverse of ``analysis.scoring.binned_px``."""
    if xy is None:
        return (np.nan, np.nan)
    return (factor * xy[0] + (factor - 1) / 2, factor * xy[1] + (factor - 1) / 2)


def frame_samples(scenario: Scenario, truth: list[TruthRecord], navigation: list[tuple[float, pus.NavigationReport]],
                  run: int = 0) -> FrameSamples:
    """The samples of image-level run ``run``: every frame the truth records, with the report of it if any."""
    u = scenario.universe
    factor = u.camera.resolution_px / scenario.obsw.imaging.binned_size_px
    reports = {nav.frame_id: nav for _, nav in navigation}
    cols: dict[str, list[Any]] = {k: [] for k in ("td", "ti", "rd", "ri", "rad_d", "rad_i", "ph", "sun")}
    for r in truth:
        if r.frame_id is None or r.los_dimorphos_inertial is None or r.los_didymos_inertial is None \
                or r.range_didymos_m is None:
            continue
        did = Body(centre_inertial_m=np.asarray(r.los_didymos_inertial) * r.range_didymos_m,
                   radius_m=u.bodies.didymos_diameter_m / 2)
        dim = Body(centre_inertial_m=np.asarray(r.los_dimorphos_inertial) * r.range_m,
                   radius_m=u.bodies.dimorphos_diameter_m / 2)
        scene = Scene(camera_position_m=np.zeros(3), q_body_to_inertial=np.asarray(r.q), body_rate_rad_s=np.zeros(3),
                      exposure_s=u.camera.exposure_s, bodies=(did, dim),
                      sun_direction=np.asarray(u.bodies.sun_direction))
        p_did, r_did, _, _ = body_view(scene, u.camera, 0)
        p_dim, r_dim, ph, sun = body_view(scene, u.camera, 1)
        nav = reports.get(r.frame_id)
        cols["td"].append(p_dim)
        cols["ti"].append(p_did)
        cols["rd"].append(full_resolution(None if nav is None else nav.dimorphos_col_row, factor))
        cols["ri"].append(full_resolution(None if nav is None else nav.didymos_col_row, factor))
        cols["rad_d"].append(r_dim)
        cols["rad_i"].append(r_did)
        cols["ph"].append(ph)
        cols["sun"].append(sun)
    arr = {k: np.asarray(v, dtype=float).reshape(len(v), 2 if k in ("td", "ti", "rd", "ri", "sun") else 1)
           for k, v in cols.items()}
    return FrameSamples(arr["td"], arr["ti"], arr["rd"], arr["ri"], arr["rad_d"][:, 0], arr["rad_i"][:, 0],
                        arr["ph"][:, 0], arr["sun"], np.full(len(cols["td"]), run, dtype=np.int64),
                        u.camera.resolution_px)


def fit_run(payload: str, k: int) -> FrameSamples:
    """Run k of an image-level campaign and return its frame samples (a Dask task)."""
    campaign = campaign_of(payload)
    run = dispersed_run(campaign.scenario, campaign.seed, k)
    out = run_in_process(run.scenario, campaign.timeline)
    tm = received_telemetry(out.received, f"run {k}")
    return frame_samples(run.scenario, out.truth, tm.navigation, k)


def _table(phase: NDArray[np.float64], values: NDArray[np.float64], ok: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Values at the table's phases: where not ``ok``, interpolated from those that are (constant beyond)."""
    if not ok.any():
        return np.zeros_like(values)
    return np.where(ok, values, np.interp(phase, phase[ok], values[ok]))


def _bins(x: NDArray[np.float64], edges: NDArray[np.float64]) -> NDArray[np.int64]:
    """The bin of each value (values beyond the edges in the end bins)."""
    return np.clip(np.digitize(x, edges) - 1, 0, edges.size - 2)


def _not_seen_tables(rep: NDArray[np.bool_], gap_bin: NDArray[np.int64], phase_bin: NDArray[np.int64],
                     n_gap: int, n_phase: int, far_from: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Merge probability per gap bin and dropout per phase bin such that a frame is seen with probability
    (1 - merge)(1 - dropout): alternating estimates, each bin's (1 - p) = frames seen / frames expected seen, then
    scaled so that gap bins from ``far_from`` on never merge."""
    merge, drop = np.zeros(n_gap), np.zeros(n_phase)
    for _ in range(ALTERNATIONS):
        for b in range(n_gap):
            m = gap_bin == b
            expected = np.sum(1.0 - drop[phase_bin[m]])
            merge[b] = 1.0 - min(1.0, rep[m].sum() / expected) if expected > 0 else 0.0
        for b in range(n_phase):
            m = phase_bin == b
            expected = np.sum(1.0 - merge[gap_bin[m]])
            drop[b] = 1.0 - min(1.0, rep[m].sum() / expected) if expected > 0 else 0.0
    # only the product is fixed by the data: discs far apart never merge, so their loss is all dropout
    far = np.arange(n_gap) >= far_from
    weights = np.bincount(gap_bin, minlength=n_gap)[far]
    keep = float(np.average(1.0 - merge[far], weights=weights)) if weights.sum() else 1.0
    if keep > 0:
        merge = 1.0 - np.minimum(1.0, (1.0 - merge) / keep)
        drop = 1.0 - (1.0 - drop) * keep
    return merge, drop


def fit_model(s: FrameSamples, tolerance_px: float) -> tuple[CentroidModelConfig, list[str]]:
    """The measurement model fitted on the samples, and lines saying what it was fitted on. ``tolerance_px``: the
    centroid error beyond which a detection is a misidentification, full-resolution px."""
    vis = s.inside(s.true_dim)
    rep = vis & np.all(np.isfinite(s.reported_dim), axis=1)
    err = s.reported_dim - s.true_dim
    misid = rep & (np.hypot(err[:, 0], err[:, 1]) > tolerance_px)
    good = rep & ~misid
    gap = np.hypot(*(s.true_dim - s.true_did).T) - s.radius_dim - s.radius_did
    phase_edges = np.arange(0.0, 180.0 + PHASE_BIN_DEG, PHASE_BIN_DEG)
    gap_edges = np.arange(GAP_RANGE_PX[0], GAP_RANGE_PX[1] + GAP_BIN_PX, GAP_BIN_PX)
    pb, gb = _bins(s.phase_dim_deg[vis], phase_edges), _bins(gap[vis], gap_edges)
    far_from = int(np.searchsorted(gap_edges, NEVER_MERGED_PX))
    merge, drop = _not_seen_tables(rep[vis], gb, pb, gap_edges.size - 1, phase_edges.size - 1, far_from)
    gap_used = [b for b in range(gap_edges.size - 1) if np.sum(gb == b) >= MIN_GAP_FRAMES]
    phases, dropout, bias, bias_ok = [], [], [], []
    along = np.sum(err * s.towards_sun_dim, axis=1)
    phase_all = _bins(s.phase_dim_deg, phase_edges)
    for b in range(phase_edges.size - 1):
        if np.sum(pb == b) < MIN_BIN_FRAMES:
            continue
        phases.append(float(np.mean(s.phase_dim_deg[vis][pb == b])))
        dropout.append(float(drop[b]))
        g = good & (phase_all == b)
        bias_ok.append(g.sum() >= MIN_BIAS_FRAMES)
        r = s.radius_dim[g]
        bias.append(float(np.sum(along[g] * r) / np.sum(r * r)) if bias_ok[-1] else 0.0)
    if not phases or not gap_used:
        raise ValueError("too few frames with Dimorphos in view for a phase or a gap bin: run more runs")
    ph = np.asarray(phases)
    bias_table = _table(ph, np.asarray(bias), np.asarray(bias_ok))
    shift = np.interp(s.phase_dim_deg, ph, bias_table)[:, None] * s.radius_dim[:, None] * s.towards_sun_dim
    res = (err - shift)[good]
    r_good = s.radius_dim[good]
    qs = np.unique(np.quantile(r_good, np.linspace(0, 1, RADIUS_BINS + 1)))
    ridx = np.clip(np.digitize(r_good, qs) - 1, 0, max(qs.size - 2, 0))
    rows, sig = [], []
    for b in range(max(qs.size - 1, 1)):
        m = ridx == b
        if m.sum() >= MIN_BIAS_FRAMES:
            rows.append((1.0, float(np.mean(r_good[m]))))
            sig.append(MAD_TO_SIGMA * float(np.median(np.abs(res[m]))))  # per axis, robust to rare outliers
    (a, slope), _ = nnls(np.asarray(rows), np.asarray(sig))
    # episodes: runs of misidentified frames, run by run, among the frames that could show one (Dimorphos and
    # Didymos reported, farther apart than the tolerance: a misidentification there is seen)
    could = rep & np.all(np.isfinite(s.reported_did), axis=1) & (np.hypot(*(s.true_dim - s.true_did).T) > tolerance_px)
    order = np.flatnonzero(could)
    flags, runs = misid[order], s.run[order]
    starts = int(np.sum(flags & ~np.r_[False, flags[:-1] & (runs[1:] == runs[:-1])]))
    episode_frames_seen = int(flags.sum())
    did_vis = s.inside(s.true_did)
    did_drop = float(np.mean(~np.all(np.isfinite(s.reported_did[did_vis]), axis=1))) if did_vis.any() else 0.0
    gap_mid = [float(np.mean(gap[vis][gb == b])) for b in gap_used]
    model = CentroidModelConfig(
        phase_deg=tuple(round(p, 3) for p in ph), bias_radius_fraction=tuple(round(float(b), 4) for b in bias_table),
        dimorphos_dropout=tuple(round(d, 4) for d in dropout), noise_px=round(float(a), 4),
        noise_radius_fraction=round(float(slope), 4), merge_gap_px=tuple(round(g, 2) for g in gap_mid),
        merge_probability=tuple(round(float(merge[b]), 4) for b in gap_used), didymos_dropout=round(did_drop, 4),
        misidentification=round(starts / max(int((could & ~misid).sum()) + starts, 1), 6),
        misidentification_frames=round(max(1.0, episode_frames_seen / starts) if starts else 1.0, 3))
    lines = [f"{vis.size} frames, {int(vis.sum())} with Dimorphos in the image, {int(rep.sum())} reporting it, "
             f"{int(misid.sum())} misidentified (> {tolerance_px:g} px) in {starts} episodes, {int(did_vis.sum())} "
             "with Didymos in it",
             f"merge table over {len(gap_used)} gap bins of {GAP_BIN_PX:g} px, dropout table over {len(ph)} phase "
             f"bins of {PHASE_BIN_DEG:g} deg",
             f"noise fitted over {len(sig)} radius bins: {a:.3f} px + {slope:.3f} x radius"]
    return model, lines


def model_yaml(model: CentroidModelConfig, header: list[str]) -> str:
    """The model file: ``universe: centroid_model: ...`` under a comment saying how it was fitted."""
    data = {"universe": {"centroid_model": model.model_dump(mode="json")}}
    return "".join(f"# {line}\n" for line in header) + yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def cmd_fit(args: argparse.Namespace) -> int:
    """Run image-level runs on Dask, fit the model, write it."""
    from distributed import as_completed

    from flyby.montecarlo.engine import dask_client
    from flyby.montecarlo.progress import Progress

    try:
        campaign = build_campaign(args.scenario, seed=args.seed, fidelity="image", dispersions=args.dispersions)
    except ScenarioError as err:
        print(err.listing("campaign"), file=sys.stderr)
        return EXIT_CONFIG
    payload = campaign.to_json()
    folder = args.samples or args.out.with_name(args.out.name + ".samples")
    folder.mkdir(parents=True, exist_ok=True)
    stamp = folder / "campaign.json"
    if stamp.is_file() and stamp.read_text(encoding="utf-8") != payload:
        print(f"flyby mc-fit: {folder} holds the samples of another campaign; choose another --samples",
              file=sys.stderr)
        return EXIT_CONFIG
    stamp.write_text(payload, encoding="utf-8")
    stored = {k: folder / f"run-{k:05d}.npz" for k in range(args.runs)}
    todo = [k for k, path in stored.items() if not path.is_file()]
    progress = Progress(args.runs, args.runs - len(todo))
    if todo:
        with dask_client(args.scheduler, args.workers, processes=not args.threads) as client:
            shared = client.scatter(payload, broadcast=True, hash=False)
            futures = {client.submit(fit_run, shared, k, pure=False): k for k in todo}
            for fut in as_completed(futures):
                fut.result().save(stored[futures[fut]])  # kept: a rerun or a refit reads it back
                progress.update(ok=True)
    progress.finish()
    parts = [FrameSamples.load(path) for path in stored.values()]
    sc = campaign.scenario
    factor = sc.universe.camera.resolution_px / sc.obsw.imaging.binned_size_px
    model, lines = fit_model(FrameSamples.concat(parts), sc.ground.report.centroid_tolerance_px * factor)
    added = f", dispersions {' + '.join(map(str, args.dispersions))}" if args.dispersions else ""
    header = [f"Centroid-level measurement model fitted by flyby mc-fit on {args.runs} image-level runs of "
              f"{args.scenario} (campaign seed {campaign.seed}{added})", *lines,
              "Positions in full-resolution px; flyby mc --fidelity centroid --centroid-model FILE uses it."]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(model_yaml(model, header), encoding="utf-8")
    print("\n".join(header))
    print(f"model: {args.out}")
    return EXIT_OK
