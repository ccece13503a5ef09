"""Fault campaigns: a small campaign run in process (two scenarios that hold, one whose expectation cannot), its
verdicts, JUnit XML, campaign page and traceability matrix; bad inputs refused before any run; the shipped fault
campaign is complete and valid."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

from analysis.runfolder import load_run
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG
from flyby.campaign import check_inputs, find_requirements
from flyby.cli import main
from scenario.model import load_run_inputs
from universe.config import FAULT_RULES

CONFIGS = Path(__file__).parents[2] / "configs"
SHORT = {  # the short closed-loop flyby of tests/obsw/test_software.py, at centroid fidelity
    "seed": 3,
    "universe": {"start_s": 110.0, "end_s": 180.0, "fidelity": "centroid", "save_frames_every": 0,
                 "link": {"one_way_light_time_s": 1.0},
                 "uncertainty": {"ca_time_offset_sigma": -0.4, "ca_distance_offset_sigma": 0.4}},
    "ground": {"timeline_file": "../timelines/short.yaml"},
}
TIMELINE = {"commands": [{"time": "CA-44s", "command": "set_mode", "args": {"mode": "ACQUISITION"}},
                         {"time": "+0s", "command": "start_imaging", "args": {"period_s": 0.5}}]}


def _campaign(tmp: Path, scenarios: dict[str, dict]) -> Path:
    """A campaign folder with its timeline and requirements beside it; the folder of scenarios."""
    (tmp / "timelines").mkdir()
    (tmp / "timelines" / "short.yaml").write_text(yaml.safe_dump(TIMELINE))
    (tmp / "requirements.yaml").write_text((CONFIGS / "requirements.yaml").read_text())
    folder = tmp / "faults"
    folder.mkdir()
    for name, extra in scenarios.items():
        data = {**SHORT, "name": name, **extra}
        data["universe"] = {**SHORT["universe"], **extra.get("universe", {})}
        (folder / f"{name}.yaml").write_text(yaml.safe_dump(data))
    return folder


WHEEL = {"universe": {"faults": [{"kind": "wheel_failed", "wheel": 1, "start_s": 128.0, "end_s": 180.0}]},
         "expect": {"events": [{"event": "WheelFailedEvent", "within_s": 10}, {"event": "FaultEvent", "within_s": 10}],
                    "final_mode": "SAFE", "wheel_momentum_max_nms": 0.1, "verifies": ["FDIR-SAFE"]}}
CLEAN = {"expect": {"in_view_min": 0.98, "no_events": ["FaultEvent"], "verifies": ["NODE-ROBUST", "FDIR-SAFE"]}}
IMPOSSIBLE = {"expect": {"final_mode": "SAFE", "events": [{"event": "FalseLockEvent"}], "verifies": ["NODE-ROBUST"]}}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path]:
    """The three-scenario campaign, run once: (exit code, output folder)."""
    tmp = tmp_path_factory.mktemp("campaign")
    folder = _campaign(tmp, {"wheel": WHEEL, "clean": CLEAN, "impossible": IMPOSSIBLE})
    out = tmp / "out"
    return main(["campaign", str(folder), "--out", str(out), "--jobs", "2"]), out


def test_exit_status_is_zero_only_if_every_expectation_holds(campaign: tuple[int, Path]) -> None:
    """One scenario cannot meet its expectations: the campaign exits 4."""
    code, _ = campaign
    assert code == EXIT_CHECK_FAILED


def test_junit_has_one_case_per_scenario_and_one_failure_per_unmet_expectation(campaign: tuple[int, Path]) -> None:
    """campaign.junit.xml parses; the impossible scenario fails twice (final mode, missing event), the others not."""
    _, out = campaign
    root = ET.parse(out / "campaign.junit.xml").getroot()
    cases = {tc.get("name"): tc for tc in root.iter("testcase")}
    assert set(cases) == {"wheel", "clean", "impossible"}
    failures = {name: [f.get("message") for f in tc.findall("failure")] for name, tc in cases.items()}
    assert failures["wheel"] == [] and failures["clean"] == []
    assert len(failures["impossible"]) == 2
    assert any(m.startswith("final mode SAFE:") for m in failures["impossible"])
    assert any(m.startswith("FalseLockEvent reported:") for m in failures["impossible"])
    assert root.get("failures") == "2" and root.find("testsuite").get("failures") == "1"


def test_each_run_has_its_folder_and_report_linked_from_the_campaign_page(campaign: tuple[int, Path]) -> None:
    """One row per scenario, each linking a report.html that exists; every run folder loads as a flyby run does."""
    _, out = campaign
    page = (out / "campaign.html").read_text()
    links = re.findall(r"href='([^']+)'", page)
    assert sorted(links) == ["clean/report.html", "impossible/report.html", "wheel/report.html"]
    assert all((out / link).is_file() for link in links)
    assert page.count("<tr>") == 1 + 3 and "2 of 3 scenarios pass every expectation" in page
    for name in ("wheel", "clean", "impossible"):
        data = load_run(out / name)
        assert data.truth is not None and data.telemetry is not None and data.telemetry.events


def test_traceability_matrix_gives_each_requirement_its_runs_and_verdict(campaign: tuple[int, Path]) -> None:
    """FDIR-SAFE verified by two passing runs passes; NODE-ROBUST, verified by the failing one too, fails; a
    requirement no run names is not assessed."""
    _, out = campaign
    rows = re.findall(r"<tr><td>([A-Z0-9-]+)</td>.*?</tr>", (out / "traceability.html").read_text(), flags=re.S)
    text = (out / "traceability.html").read_text()

    def verdict(req: str) -> str:
        row = re.search(rf"<tr><td>{req}</td>.*?</tr>", text, flags=re.S)
        assert row is not None
        return re.findall(r'class="(pass|fail|na)"', row.group(0))[-1]

    assert "PAPER-RATE" in rows and verdict("FDIR-SAFE") == "pass" and verdict("NODE-ROBUST") == "fail"
    assert verdict("PAPER-RATE") == "na"


def test_bad_campaign_inputs_are_refused_before_any_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A scenario without an expect: block and one naming an unknown requirement: exit 2, each named, nothing run."""
    folder = _campaign(tmp_path, {"bare": {}, "unknown": {"expect": {"verifies": ["NO-SUCH"]}}})
    assert main(["campaign", str(folder), "--out", str(tmp_path / "out")]) == EXIT_CONFIG
    err = capsys.readouterr().err
    assert "bare.yaml: expect: a campaign scenario needs an expect: block" in err
    assert "unknown.yaml: expect.verifies: 'NO-SUCH' is not a requirement" in err
    assert not (tmp_path / "out").exists()


def test_the_shipped_fault_campaign_is_valid_and_covers_every_fault_kind() -> None:
    """configs/scenarios/faults: at least 16 scenarios, each valid with an expect: block naming known requirements,
    every universe fault kind injected by at least one, and wheel 1 at C/A-60 s on both wheel layouts."""
    folder = CONFIGS / "scenarios" / "faults"
    paths, reqs, problems = check_inputs(folder, CONFIGS / "requirements.yaml")
    assert problems == [] and reqs is not None and len(paths) >= 16
    scenarios = [load_run_inputs(p)[0] for p in paths]
    kinds = {f.kind for s in scenarios for f in s.universe.faults}
    assert kinds == set(FAULT_RULES)
    wheel1 = {s.universe.spacecraft.wheels.layout for s in scenarios for f in s.universe.faults
              if f.kind in ("wheel_failed", "wheel_stuck") and f.wheel == 1 and f.start_s == 108.0}
    assert wheel1 == {"orthogonal", "pyramid"}
    verified = {i for s in scenarios for i in s.expect.verifies}  # type: ignore[union-attr]
    assert verified == {r.id for r in reqs.requirements}


def test_a_requirements_file_in_the_folder_is_not_taken_for_a_scenario(tmp_path: Path) -> None:
    """The folder's own requirements.yaml is the campaign's requirements, not a scenario to run."""
    folder = _campaign(tmp_path, {"clean": CLEAN})
    (folder / "requirements.yaml").write_text((CONFIGS / "requirements.yaml").read_text())
    paths, reqs, problems = check_inputs(folder, find_requirements(folder))
    assert problems == [] and [p.name for p in paths] == ["clean.yaml"]
    assert reqs is not None and find_requirements(folder) == (folder / "requirements.yaml").resolve()


def test_a_second_campaign_into_the_same_folder_is_refused_unless_replaced(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Run folders left by an earlier campaign are refused by name (exit 2, untouched); with --replace they are run
    again from scratch, so the archive holds one run's packets, not two."""
    folder = _campaign(tmp_path, {"clean": CLEAN})
    out = tmp_path / "out"
    assert main(["campaign", str(folder), "--out", str(out), "--jobs", "1"]) == 0
    first = load_run(out / "clean")
    assert first.telemetry is not None
    packets = first.telemetry.packets
    before = (out / "clean" / "tm.bin").read_bytes()
    capsys.readouterr()
    assert main(["campaign", str(folder), "--out", str(out), "--jobs", "1"]) == EXIT_CONFIG
    assert f"{out / 'clean'}: holds a run already" in capsys.readouterr().err
    assert (out / "clean" / "tm.bin").read_bytes() == before
    assert main(["campaign", str(folder), "--out", str(out), "--jobs", "1", "--replace"]) == 0
    again = load_run(out / "clean")
    assert again.telemetry is not None and again.telemetry.packets == packets
    assert (out / "clean" / "tm.bin").read_bytes() == before  # deterministic: the same run, once
