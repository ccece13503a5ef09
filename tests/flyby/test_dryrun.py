"""The timeline dry run: it warns of the early-knowledge case (the C/A-240 s rows already past at upload, uploaded and
released on arrival) and passes the nominal, with release times where ground's tags and the on-board re-anchoring put
them."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from contracts.exitcodes import EXIT_CONFIG
from flyby.cli import main
from flyby.dryrun import CaseResult, _insert_refusals, cases, dry_run, rehearsal_scenario
from scenario import compose
from scenario.model import Scenario, load_run_inputs, load_scenario
from timeline.model import AfterPreviousTag, CaTag, Timeline
from timeline.parse import load_timeline
from universe.geometry import dimorphos_line

CONFIGS = Path(__file__).parents[2] / "configs"
TIMELINE = CONFIGS / "timelines" / "flyby-imaging.yaml"
NOMINAL = CONFIGS / "scenarios" / "nominal.yaml"
EARLY = CONFIGS / "scenarios" / "ground-early-knowledge.yaml"


def _ca_offsets(timeline: Timeline) -> list[float]:
    """Each row's offset from C/A, following '+Ns' rows from the row before (the timeline language's rule)."""
    out: list[float] = []
    for e in timeline.entries:
        tag = e.tag
        assert isinstance(tag, (CaTag, AfterPreviousTag))
        out.append(tag.ca_offset_s if isinstance(tag, CaTag) else out[-1] + tag.delay_s)
    return out


@pytest.fixture(scope="module")
def nominal() -> tuple[Scenario, Timeline, list[CaseResult]]:
    """The nominal scenario's dry run of the imaging timeline, every case."""
    sc, timeline = load_run_inputs(NOMINAL)
    assert timeline is not None
    return sc, timeline, dry_run(sc, timeline, jobs=2)


def test_case_world_is_grounds_belief_moved_by_the_case(tmp_path: Path) -> None:
    """A case's true flyby of Dimorphos is ground's belief plus k sigma, ground in it believes exactly the belief,
    its on-board time is UTC plus the a-priori offset, and it has no faults."""
    sc = load_scenario(NOMINAL)
    belief = compose.ground_belief(sc)
    for case in cases():
        world = rehearsal_scenario(sc, belief, case)
        f = dimorphos_line(world.universe.flyby, world.universe.bodies)
        assert f.ca_time_s == pytest.approx(belief.ca_utc_s + case.time_sigma * belief.ca_time_sigma_s, abs=1e-9)
        far = case.distance_sigma * belief.ca_distance_sigma_km
        assert f.ca_distance_km == pytest.approx(belief.ca_distance_km + far, abs=1e-9)
        assert np.allclose(f.ca_direction, belief.ca_direction, rtol=0.0, atol=1e-12)
        seen = compose.ground_belief(world)
        assert seen.ca_utc_s == pytest.approx(belief.ca_utc_s, abs=1e-9)
        assert seen.ca_distance_km == pytest.approx(belief.ca_distance_km, abs=1e-9)
        osc = world.universe.oscillator
        assert (osc.initial_offset_s, osc.drift_ppm, osc.jitter_s) == (sc.ground.a_priori_obt_offset_s, 0.0, 0.0)
        assert world.universe.faults == [] and world.universe.fidelity == "centroid"
    assert {(c.time_sigma, c.distance_sigma) for c in cases()} == {(0, 0), (-3, -3), (-3, 3), (3, -3), (3, 3)}


def test_a_case_ends_after_its_last_release_and_its_scoring_window() -> None:
    """A case stops once its last row is released (on ground's C/A or on the true one, whichever is later) and the
    in-view window after the true C/A has closed, never after the scenario's end."""
    sc, timeline = load_run_inputs(NOMINAL)
    assert timeline is not None
    belief = compose.ground_belief(sc)
    last = max(_ca_offsets(timeline))
    for case in cases():
        world = rehearsal_scenario(sc, belief, case, timeline=timeline)
        true_ca = dimorphos_line(world.universe.flyby, world.universe.bodies).ca_time_s
        wanted = max(belief.ca_utc_s + last, true_ca + last, true_ca + sc.ground.report.in_view_after_ca_s)
        assert wanted < world.universe.end_s <= min(sc.universe.end_s, wanted + 6.0)


def test_early_knowledge_is_flagged(capsys: pytest.CaptureFixture[str]) -> None:
    """Ground's C/A 23.6 s early: the rows whose C/A tag falls before upload + light time + margin (computed here from
    the scenario) are uploaded late with a warning in every case, and released on board on arrival: the flyby
    passes."""
    sc = load_scenario(EARLY)
    timeline = load_timeline(TIMELINE)
    g = sc.ground
    unc = sc.universe.uncertainty
    assert unc.ca_time_offset_sigma is not None
    ca = sc.universe.flyby.ca_time_s + unc.ca_time_offset_sigma * unc.ca_time_sigma_s
    reach = sc.universe.start_s + g.link.one_way_light_time_s + g.upload_margin_s
    late = [row for row, off in enumerate(_ca_offsets(timeline), start=1) if ca + off < reach]
    assert late == [1, 2]  # the C/A-240 s pair: the case this scenario reproduces
    code = main(["ground", "--dry-run", str(TIMELINE), "--scenario", str(EARLY), "--jobs", "2"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert out.count("executed LATE: uploaded after its time, released on arrival") == len(late) * len(cases())
    for row in late:
        assert f"WARNING: row {row} (" in out and f"in {len(cases())} of {len(cases())} cases" in out


def test_nominal_passes(nominal: tuple[Scenario, Timeline, list[CaseResult]]) -> None:
    """The nominal timeline: every row uploaded, released and executed, every requirement holds, in all cases."""
    _, timeline, results = nominal
    assert [r.case for r in results] == cases()
    for r in results:
        assert r.error is None
        assert [c.row for c in r.commands] == list(range(1, len(timeline.entries) + 1))
        assert all(c.ok for c in r.commands), [c for c in r.commands if not c.ok]
        assert r.figures is not None and r.figures.all_pass, r.figures.summary_lines() if r.figures else None
        assert r.ok
        assert [m[2] for m in r.mode_path][0] == "ACQUISITION" and r.mode_path[-1][2] == "STANDBY"


def test_release_times(nominal: tuple[Scenario, Timeline, list[CaseResult]]) -> None:
    """In ground's belief every row is released at the first control period at or after OBT = a-priori offset +
    believed C/A + its offset; in the corners the rows after autonomous tracking began are re-anchored on the
    recognised trajectory, within 0.25 s of the true C/A plus their offset."""
    sc, timeline, results = nominal
    belief = compose.ground_belief(sc)
    offset, dt = sc.ground.a_priori_obt_offset_s, sc.universe.control_period_s
    offsets = _ca_offsets(timeline)
    start_obt = offset + sc.universe.start_s
    for c, off in zip(results[0].commands, offsets, strict=True):
        tag = offset + belief.ca_utc_s + off
        expected = start_obt + math.ceil((tag - start_obt) / dt - 1e-6) * dt
        assert c.release_obt_s == pytest.approx(expected, abs=1e-3), c
    for r in results[1:]:
        autonomy = next(t for t, _, to, _ in r.mode_path if to == "AUTONOMOUS_TRACKING")
        for c, off in zip(r.commands, offsets, strict=True):
            assert c.release_obt_s is not None
            if c.release_obt_s > autonomy + dt / 2:
                assert c.release_obt_s - offset == pytest.approx(r.true_ca_utc_s + off, abs=0.25), (r.case, c)
            else:  # still on ground's tag
                assert c.release_obt_s - offset == pytest.approx(belief.ca_utc_s + off, abs=dt + 1e-3), (r.case, c)


def test_insert_refusal_text_is_split_by_activity() -> None:
    """The on-board schedule's 'activity i: why; activity j: why' completion text gives each index its reason."""
    text = "activity 0: release time in the past; activity 3: schedule full (capacity 64)"
    assert _insert_refusals(text) == {0: "release time in the past", 3: "schedule full (capacity 64)"}
    assert _insert_refusals("no activity named") == {}


def test_bad_inputs_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No --scenario, a timeline repeating a row and a trajectory file without a C/A time are refused before any run,
    each named."""
    assert main(["ground", "--dry-run", str(TIMELINE)]) == EXIT_CONFIG
    assert "--scenario" in capsys.readouterr().err
    twice = tmp_path / "twice.yaml"
    row = {"time": "CA-100s", "command": "stop_imaging"}
    twice.write_text(yaml.safe_dump({"commands": [row, row]}))
    assert main(["ground", "--dry-run", str(twice), "--scenario", str(NOMINAL)]) == EXIT_CONFIG
    assert "row 2: repeats row 1" in capsys.readouterr().err
    traj = tmp_path / "traj.yaml"
    traj.write_text(yaml.safe_dump({"ca_distance_km": 50.0}))
    assert main(["ground", "--dry-run", str(TIMELINE), "--scenario", str(NOMINAL), "--trajectory", str(traj)]) == \
        EXIT_CONFIG
    assert "exactly one of ca_time_utc and ca_time_s" in capsys.readouterr().err


_AFTER_OPENCV_THREADS = """
import sys
from pathlib import Path
import cv2
import numpy as np
from flyby.dryrun import dry_run
from scenario.model import load_run_inputs
cv2.setNumThreads(2)
image = np.random.default_rng(0).random((1500, 1500)).astype(np.float32)
for _ in range(4):  # OpenCV's pool of threads started and left waiting, as any earlier work in the process leaves it
    cv2.GaussianBlur(image, (31, 31), 5.0)
sc, timeline = load_run_inputs(Path(sys.argv[1]))
results = dry_run(sc, timeline, jobs=2)
print(len(results), cv2.getNumThreads())
"""


def test_a_dry_run_forks_its_cases_safely_after_opencv_ran_threads() -> None:
    """A process that ran OpenCV on several threads, then dry-runs with two jobs: every case comes back (a child
    reconfiguring the pool it inherited used to wait forever), and the process keeps its OpenCV threads."""
    root = Path(__file__).parents[2]
    done = subprocess.run([sys.executable, "-c", _AFTER_OPENCV_THREADS, str(NOMINAL)], cwd=root, capture_output=True,
                          text=True, timeout=240)  # generous (a dry run here takes 15 s): the hang never ended
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == [str(len(cases())), "2"]
