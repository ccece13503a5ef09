"""The kept Monte Carlo runs (configs/scenarios/mc/) replayed alone in one process keep the requirement they once
missed, scored against the universe's truth by the report's own scoring."""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

import pytest

from analysis.runfolder import RunData
from analysis.scoring import centroid_errors_px, score_run
from analysis.telemetry import received_telemetry
from analysis.truth import Truth
from contracts.messages import TruthRecord
from flyby.inprocess import run_in_process
from ground.segment import ReceivedPacket
from scenario.model import load_run_inputs

KEPT = Path(__file__).resolve().parents[2] / "configs" / "scenarios" / "mc"
Outcome = tuple[list[TruthRecord], list[ReceivedPacket]]  # a run's truth and the telemetry ground received
NAMES = ("nominal-run00545", "nominal-run00345", "nominal-run00957", "nominal-run00432", "nominal-run00218",
         "nominal-run00127", "nominal-run00881", "nominal-run00509", "worst-late-near-run00073",
         "worst-late-near-run00022", "worst-late-near-run00039", "worst-late-near-run00026",
         "worst-late-near-run00085", "worst-late-near-run00165", "worst-late-near-run00272",
         "worst-late-near-run00626")


def _run(name: str) -> Outcome:
    """The kept scenario ``name`` run alone in one process."""
    scenario, timeline = load_run_inputs(KEPT / f"{name}.yaml")
    out = run_in_process(scenario, timeline)
    return out.truth, out.received


@pytest.fixture(scope="module")
def runs() -> Iterator[dict[str, Future[Outcome]]]:
    """Every kept run, started at once over two fresh processes (each test waits for its own)."""
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield {name: pool.submit(_run, name) for name in NAMES}


def _replayed(runs: dict[str, Future[Outcome]], name: str) -> RunData:
    """The kept scenario ``name``'s run, as the report reads a run."""
    truth, received = runs[name].result()
    scenario, _ = load_run_inputs(KEPT / f"{name}.yaml")
    return RunData(Path(f"<{name}>"), scenario, Truth.from_records(truth), received_telemetry(received, name))


def _assert_centroids_within_10_px(data: RunData, min_count: int = 300) -> None:
    ids, errors = centroid_errors_px(data)
    assert ids.size >= min_count, ids.size
    worst = int(errors.argmax())
    assert errors[worst] <= 10.0, f"frame {ids[worst]}: {errors[worst]:.2f} px"


def test_run_545_keeps_every_centroid_near_dimorphos(runs: dict[str, Future[Outcome]]) -> None:
    """Run 545 of the 1000-run campaign (the plume's fan taken for Didymos at C/A-57 s, with ground's nominal 2.3
    sigma off in C/A time; Dimorphos cut with the plume's core behind it at C/A-3.5 s) reports every Dimorphos
    centroid within 10 px of its true centre: the frame predicted from the recognised trajectory, the cut checked
    against Dimorphos's limb."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00545"))


def test_run_345_keeps_the_target_when_the_plume_outshines_didymos(runs: dict[str, Future[Outcome]]) -> None:
    """Run 345 of the image-level campaign after the settle gate (the plume 2.3 times the nominal's light, its fan
    merged with Didymos and taken for it from C/A-152 s, a piece of Didymos 9-16 px from Dimorphos taken for
    Dimorphos) keeps every requirement: Dimorphos is searched only where the lock gate would accept its line of sight,
    so the estimate is never fed the piece of Didymos."""
    data = _replayed(runs, "nominal-run00345")
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.in_view_pass and figs.pointing_pass and figs.centroid_pass, figs


def test_run_957_keeps_dimorphos_beside_didymos_limb_by_its_own_limb(runs: dict[str, Future[Outcome]]) -> None:
    """Run 957 of the image-level campaign on a6e17b5 (at C/A-5 s Dimorphos touches Didymos's limb and its cut kept
    the limb beside it, 20.7 px off) reports every Dimorphos centroid within 10 px of its true centre: the circle of
    Dimorphos's limb, found where the prediction puts it, replaces the cut."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00957"))


def test_run_432_finds_dimorphos_by_its_limb_at_63_deg_of_phase(runs: dict[str, Future[Outcome]]) -> None:
    """Run 432 of the image-level campaign (at C/A+5 s Dimorphos, at 63 deg of phase with its terminator towards
    Didymos, in front of Didymos's limb; its cut by brightness kept Didymos's brighter surface, 15.35 px off) reports
    every Dimorphos centroid within 10 px of its true centre: the limb check runs up to 70 deg of phase (90 since)."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00432"))


def test_run_218_does_not_take_a_smeared_star_beside_the_crescent_for_dimorphos(
        runs: dict[str, Future[Outcome]]) -> None:
    """Run 218 of the image-level campaign on c97a1a7 (at C/A+16 s a star smeared by the slew lay 14 px below a 7 px
    crescent merged with the plume, within the body's largest radius of a place known to 3.2 px, and was reported as
    Dimorphos: 14.80 px) reports every Dimorphos centroid within 10 px of its true centre: a candidate must lie where
    the lit part's centroid is expected when any does."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00218"))


def test_run_127_cuts_the_crescent_from_the_plume_core_as_bright_beside_it(runs: dict[str, Future[Outcome]]) -> None:
    """Run 127 of the image-level campaign on 75ed4d8 (at C/A+6 s, 93 deg of phase, the plume's core as bright as
    the crescent beside it made one part of their region's brightest pixels, 11 px off the lit part's expected
    centroid: 10.35 px) reports every Dimorphos centroid within 10 px of its true centre: a higher level parts
    them."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00127"))


def test_run_881_takes_the_limb_on_the_place_for_a_cut_off_it(runs: dict[str, Future[Outcome]]) -> None:
    """Run 881 of the image-level campaign on 70e093e (at C/A-6 s, 20 deg of phase, the cut of the region Dimorphos
    shares with Didymos lay 7.5 px from a place known to 4 px and within half a radius of the limb's circle on the
    place, and was kept: 11.10 px) reports every Dimorphos centroid within 10 px of its true centre."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00881"))


def test_run_509_fits_the_limb_of_dimorphos_parted_from_its_plume_s_glow(runs: dict[str, Future[Outcome]]) -> None:
    """Run 509 of the image-level campaign on 564b721 (frame 322, the first where Dimorphos parts from its plume's
    glow beside Didymos's limb: the brightest part of its deblended object, pulled towards the glow, was reported
    without a limb fit, 11.56 px off) reports every Dimorphos centroid within 10 px of its true centre."""
    _assert_centroids_within_10_px(_replayed(runs, "nominal-run00509"))


def test_late_corner_run_73_images_once_the_slew_onto_the_target_is_done(runs: dict[str, Future[Outcome]]) -> None:
    """Run 73 of the worst-late-near campaign (centroid level; STANDBY's attitude 1.56 deg off the target when
    ACQUISITION began, past half the field of view) exposes its first frame after the slew, and keeps the pointing
    error under half the field of view and the target in every frame from then on."""
    data = _replayed(runs, "worst-late-near-run00073")
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.pointing_pass, f"{figs.max_pointing_error_deg:.3f} deg"
    assert figs.in_view_fraction == 1.0


def test_late_corner_run_22_finds_dimorphos_in_a_bright_plume_by_its_limb(runs: dict[str, Future[Outcome]]) -> None:
    """Run 22 of a worst-late-near campaign (Dimorphos inside a plume's fan as bright as its surface, C/A+5 to +9 s at
    73-90 deg of phase; its cuts 10-11 px off the centre when the limb check ran only up to 70 deg) reports every
    Dimorphos centroid taken between 70 and 90 deg of phase within 5 px of its true centre (4.1 measured, 4.6 since
    the recognition's cross-check with Didymos moved the loop: the predicted place is 3.6-8.3 px off there, so the
    limb's circle is not taken; 1.7 px when a circle near the cut was taken off the place too, which put the nominal
    flyby's C/A+3 s frame 13 px off), and keeps every requirement."""
    data = _replayed(runs, "worst-late-near-run00022")
    truth, _ = runs["worst-late-near-run00022"].result()
    phase_of = {r.frame_id: r.phase_angle_deg for r in truth if r.frame_id is not None and r.frame_id >= 0}
    ids, errors = centroid_errors_px(data)
    steep = [(int(f), float(e)) for f, e in zip(ids, errors, strict=True) if 70.0 <= phase_of[int(f)] <= 90.0]
    assert len(steep) >= 5, steep
    assert max(e for _, e in steep) <= 5.0, steep
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.all_pass, figs


def test_worst_late_near_run_39_points_on_didymos_while_dimorphos_goes_unseen(
        runs: dict[str, Future[Outcome]]) -> None:
    """Run 39 of the worst-late-near campaign of seed 2026 (Dimorphos a point at its plume's root, seen a few
    frames and lost for tens of seconds before its trajectory is recognised, ground's nominal 3 sigma late and near)
    keeps every requirement: Didymos's recognised trajectory, not the nominal, is pointed on while Dimorphos is
    unseen (it missed the pointing, 1.61 deg, on the nominal)."""
    data = _replayed(runs, "worst-late-near-run00039")
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.in_view_pass and figs.pointing_pass and figs.centroid_pass and figs.rate_pass, figs


@pytest.mark.parametrize("name", ["worst-late-near-run00026", "worst-late-near-run00085"])
def test_worst_late_near_keeps_the_pair_apart_when_the_plume_merges_with_didymos(
        runs: dict[str, Future[Outcome]], name: str) -> None:
    """Runs 26 and 85 of the worst-late-near campaign of seed 2026 (the plume's root merged with Didymos while the
    camera pointed on ground's nominal, Didymos far off the centre; the pair was swapped for 100 s, 46 and 22 px)
    keep every requirement with Didymos's trajectory pointed on from the tenth second of ACQUISITION."""
    data = _replayed(runs, name)
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.in_view_pass and figs.pointing_pass and figs.centroid_pass and figs.rate_pass, figs


def test_worst_late_near_run_165_remembers_the_pair_while_dimorphos_is_merged_with_its_fan(
        runs: dict[str, Future[Outcome]]) -> None:
    """Run 165 of the worst-late-near campaign of seed 2026 (at 900-1000 km Dimorphos merged with its fan's root and
    Didymos for 20 frames; the pair forgotten, the brighter fan root taken for Didymos, the swap carried 40 frames and
    Dimorphos's trajectory recognised off by it, 20.9 px after C/A) keeps every requirement, its Dimorphos centroids
    within 10 px of the truth: the pair of a smaller, farther Didymos is remembered longer."""
    data = _replayed(runs, "worst-late-near-run00165")
    _assert_centroids_within_10_px(data, min_count=250)  # Dimorphos, merged with its fan, unseen many frames far out
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.all_pass, figs


def test_worst_late_near_run_626_keeps_didymos_beside_a_fan_brighter_than_it(
        runs: dict[str, Future[Outcome]]) -> None:
    """Run 626 of the worst-late-near campaign of seed 2026 (from 1080 km a 9 px Didymos merged with Dimorphos's fan,
    whose root, brighter, held every pixel of the region's brightest cut: the root taken for Didymos to C/A-30 s, the
    target lost, 2.8 deg off at C/A) keeps every requirement, its Dimorphos centroids within 10 px of the truth:
    Didymos is where the last pair's offset puts it from Dimorphos's place, found among the region's objects."""
    data = _replayed(runs, "worst-late-near-run00626")
    _assert_centroids_within_10_px(data, min_count=250)
    figs, _ = score_run(data, data.scenario.ground.report)
    assert figs.all_pass, figs


def test_worst_late_near_run_272_takes_the_limb_over_a_cut_of_the_jet_above_it(
        runs: dict[str, Future[Outcome]]) -> None:
    """Run 272 of the worst-late-near campaign of seed 2026 (at C/A-3 s a 27 px Dimorphos in front of its plume's jet
    was cut on the jet's root above its limb, 13.95 px off; its limb's circle, 3.3 px off the centre, lay 6.4 px off a
    place known to 4 px) reports every Dimorphos centroid within 10 px of the truth: off the place, the circle nearer
    it than the cut is taken."""
    _assert_centroids_within_10_px(_replayed(runs, "worst-late-near-run00272"))
