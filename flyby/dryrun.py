"""The dry run of a command timeline before uplink (``flyby ground --dry-run TIMELINE --scenario S``).

The timeline goes through ground's upload and the flight software in process, faster than real time, against the
universe as ground believes it: a flyby whose truth is ground's nominal trajectory (``compose.ground_belief``, or a
trajectory file), on-board time running exactly as ground's a-priori correlation says, no fault. Then against
ground's 3-sigma corners: the truth at C/A time +-3 sigma and C/A distance +-3 sigma, ground's belief unchanged.
Per case and command: the release time on board (OBT, and its UTC), accepted or refused with the reason (by ground
at upload, by the on-board schedule, or at execution), the mode path, and whether the flyby requirements hold
(``analysis.scoring.score_run``). A timeline ground would refuse at upload is caught here, never in flight.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from datetime import timedelta
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from analysis.runfolder import RunData
from analysis.scoring import RunFigures, score_run
from analysis.telemetry import received_telemetry
from analysis.truth import Truth
from contracts import pus
from contracts.errors import ScenarioError
from contracts.messages import StepReply, StepRequest
from flyby.inprocess import run_in_process
from ground.config import FlybyBelief, ReportConfig
from ground.segment import RowUpload
from scenario import compose
from scenario.model import Scenario, scenario_from_dict
from timeline.convert import epoch_datetime
from timeline.model import Timeline
from universe.config import FlybyConfig
from universe.geometry import barycentre_flyby

CORNER_SIGMA = 3.0  # ground's corners: C/A time and distance this many one-sigma off its belief (the paper's 3-sigma)
END_MARGIN_S = 5.0  # a case runs this long past its last release and its scoring window (the on-board C/A a second off)


class DryRunInputError(ValueError):
    """The dry run cannot start; ``problems`` names each file and what is wrong."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__("; ".join(problems))


@dataclass(frozen=True)
class Case:
    """One world of the dry run: the truth placed ``time_sigma`` and ``distance_sigma`` one-sigmas off ground's
    belief (0, 0: the belief itself)."""

    name: str
    time_sigma: float
    distance_sigma: float

    def description(self) -> str:
        """What the case's truth is, relative to ground's belief."""
        if self.time_sigma == 0 and self.distance_sigma == 0:
            return "the truth is ground's belief"
        return f"true C/A time {self.time_sigma:+g} sigma, distance {self.distance_sigma:+g} sigma off ground's belief"


def cases(k: float = CORNER_SIGMA) -> list[Case]:
    """Ground's belief, then its four corners: C/A time -+k sigma (early, late) by distance -+k sigma (near, far)."""
    out = [Case("belief", 0.0, 0.0)]
    for ts, tn in ((-k, "early"), (k, "late")):
        for ds, dn in ((-k, "near"), (k, "far")):
            out.append(Case(f"{tn}-{dn}", ts, ds))
    return out


def rehearsal_scenario(sc: Scenario, belief: FlybyBelief, case: Case, upload_utc_s: float | None = None,
                       fidelity: str = "centroid", timeline: Timeline | None = None) -> Scenario:
    """The scenario of one case: the truth is ground's belief moved by the case's sigmas, ground believes
    ``belief`` (the uncertainty offsets cancel the move), the oscillator is ground's a-priori correlation (no drift,
    no jitter), no faults, the timeline given separately; ``upload_utc_s``: the run starts and ground uploads then
    (a live run's current time), else as the scenario says; ``fidelity``: centroid (the imaging chain's output
    modelled, fast) or image (frames rendered and processed); ``timeline``: the case ends once its last command is
    released and the scoring window has closed (``case_end_s``), not later than the scenario. ScenarioError if the
    case cannot be built."""
    data: dict[str, Any] = sc.model_dump(mode="json")
    u = data["universe"]
    u["fidelity"] = fidelity
    if upload_utc_s is not None:
        u["start_s"], data["ground"]["upload_nominal_at_s"] = upload_utc_s, None
    target = case_target(belief, case)
    flyby = barycentre_flyby(target, sc.universe.bodies)  # ground's belief is Dimorphos's flyby
    u["flyby"].update(ca_time_s=flyby.ca_time_s, ca_distance_km=flyby.ca_distance_km, speed_km_s=flyby.speed_km_s,
                      approach_direction=list(flyby.approach_direction), ca_direction=list(flyby.ca_direction))
    u["uncertainty"] = {"ca_time_sigma_s": belief.ca_time_sigma_s, "ca_distance_sigma_km": belief.ca_distance_sigma_km,
                        "ca_time_offset_sigma": -case.time_sigma, "ca_distance_offset_sigma": -case.distance_sigma}
    u["oscillator"] = {"initial_offset_s": sc.ground.a_priori_obt_offset_s}
    u["faults"] = []
    data["ground"]["timeline_file"] = None
    data["name"] = f"{sc.name}-dry-run"
    if timeline is not None:
        end = case_end_s(sc, belief, timeline, target.ca_time_s)
        if end is not None and u["start_s"] < end < u["end_s"]:
            u["end_s"] = u["start_s"] + math.ceil((end - u["start_s"]) / sc.universe.control_period_s) \
                * sc.universe.control_period_s
    return scenario_from_dict(data, f"dry run case '{case.name}'")


def case_target(belief: FlybyBelief, case: Case) -> FlybyConfig:
    """The case's true flyby of Dimorphos: ground's belief moved by the case's sigmas in C/A time and distance."""
    return FlybyConfig(ca_time_s=belief.ca_utc_s + case.time_sigma * belief.ca_time_sigma_s,
                       ca_distance_km=belief.ca_distance_km + case.distance_sigma * belief.ca_distance_sigma_km,
                       speed_km_s=belief.speed_km_s, approach_direction=belief.approach_direction,
                       ca_direction=belief.ca_direction)


def case_end_s(sc: Scenario, belief: FlybyBelief, timeline: Timeline, true_ca_utc_s: float) -> float | None:
    """When a case has shown all it can (UTC s): its last command released and the requirements' window after the
    true C/A closed, plus ``END_MARGIN_S``; None if the timeline cannot be resolved (the whole scenario is run, and
    ground reports why). Tags are resolved as ground resolves them on its belief, and again on the true C/A: in
    autonomous tracking the flight software moves its C/A-relative commands to the C/A it recognised."""
    from ground.correlation import Correlation
    from timeline.convert import resolved_commands
    from timeline.model import TimelineError

    clock = Correlation.exact(sc.ground.a_priori_obt_offset_s, 0.0)  # the dry run's on-board time
    last_utc = -math.inf
    for ca_utc_s in (belief.ca_utc_s, true_ca_utc_s):
        try:
            rows = resolved_commands(timeline, clock, epoch_utc=sc.epoch_utc, ca_utc_s=ca_utc_s)
        except TimelineError:
            return None
        last_utc = max([last_utc, *(clock.to_utc(r.obt_s) for r in rows)])
    return max(last_utc, true_ca_utc_s + sc.ground.report.in_view_after_ca_s) + END_MARGIN_S


@dataclass(frozen=True)
class CommandOutcome:
    """What became of one timeline row in one case."""

    row: int
    command: str
    uploaded_obt_s: float  # the release OBT ground resolved at upload
    ca_offset_s: float | None
    refused: str | None  # by ground at upload, by the on-board schedule, or at execution: who and why
    release_obt_s: float | None  # when the on-board schedule released it (None: refused or never released)
    release_utc: str | None
    late: str | None = None  # ground's warning: tied to C/A and due before it can arrive, released on arrival

    @property
    def ok(self) -> bool:
        """Uploaded, inserted, released and executed."""
        return self.refused is None and self.release_obt_s is not None


@dataclass
class CaseResult:
    """One case of the dry run: its commands, its mode path and its requirement figures."""

    case: Case
    true_ca_utc_s: float
    true_ca_distance_km: float
    commands: list[CommandOutcome] = field(default_factory=list)
    mode_path: list[tuple[float, str, str, str]] = field(default_factory=list)  # (OBT, from, to, cause)
    figures: RunFigures | None = None
    error: str | None = None  # the case could not be run: why

    @property
    def commands_ok(self) -> bool:
        """Every row accepted and executed."""
        return self.error is None and all(c.ok for c in self.commands)

    @property
    def ok(self) -> bool:
        """Every row executed and every requirement assessed and passed."""
        return self.commands_ok and self.figures is not None and self.figures.all_pass


def utc_text(epoch_utc: str, utc_s: float) -> str:
    """UTC of ``utc_s`` seconds after the epoch, ISO 8601 to the millisecond."""
    t = epoch_datetime(epoch_utc) + timedelta(seconds=utc_s)
    return t.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _insert_refusals(text: str) -> dict[int, str]:
    """Per activity index, the on-board schedule's refusal in a TC[11,4] completion failure ('activity i: why; ...')."""
    parts = re.split(r"(?:^|; )activity (\d+): ", text)
    return {int(parts[i]): parts[i + 1] for i in range(1, len(parts) - 1, 2)}


def _outcomes(rows: Sequence[RowUpload], verifications: list[tuple[float, pus.Verification]],
              insert_seqs: set[int], oscillator_offset_s: float, epoch_utc: str) -> list[CommandOutcome]:
    """Each row's fate from ground's upload record and the on-board verification reports."""
    sent = sorted((r for r in rows if r.seq_count is not None), key=lambda r: (r.obt_s, r.row))
    index = {r.row: i for i, r in enumerate(sent)}  # the insert lists the accepted rows in OBT order
    on_board: dict[int, str] = {}
    done: dict[int, tuple[float, pus.Verification]] = {}
    for obt, v in verifications:
        seq = v.request_id.seq_count
        if seq in insert_seqs and v.stage == pus.Stage.COMPLETION and not v.success:
            on_board.update(_insert_refusals(v.reason))
        elif v.stage == pus.Stage.COMPLETION and seq not in done:
            done[seq] = (obt, v)
    out = []
    for r in rows:
        refused, release = r.refused and f"refused by ground at upload: {r.refused}", None
        if refused is None and index[r.row] in on_board:
            refused = f"refused by the on-board schedule: {on_board[index[r.row]]}"
        elif refused is None and r.seq_count in done:
            release, v = done[r.seq_count]
            if not v.success:
                refused = f"failed on board at OBT {release:.3f} s: code 0x{v.failure_code:04X} {v.reason}"
        elif refused is None:
            refused = "never released: still in the on-board schedule when the run ended"
        utc = None if release is None else utc_text(epoch_utc, release - oscillator_offset_s)
        out.append(CommandOutcome(r.row, r.command, r.obt_s, r.ca_offset_s, refused, release, utc, r.late))
    return out


def rehearse_case(sc: Scenario, timeline: Timeline, belief: FlybyBelief, case: Case,
                  upload_utc_s: float | None = None, fidelity: str = "centroid") -> CaseResult:
    """Run one case in process and collect its outcome."""
    try:
        world = rehearsal_scenario(sc, belief, case, upload_utc_s, fidelity, timeline)
    except ScenarioError as err:
        return CaseResult(case, float("nan"), float("nan"), error="; ".join(err.problems))
    target = case_target(belief, case)  # the true C/A is Dimorphos's, as the report's
    result = CaseResult(case, target.ca_time_s, target.ca_distance_km)
    insert_seqs: set[int] = set()

    def on_step(req: StepRequest, reply: StepReply, frame: np.ndarray | None) -> None:
        for raw in req.uplink:
            try:
                header, cmd = pus.decode_tc(raw, expected_apid=world.obsw.apid)
            except pus.PacketError:
                continue
            if isinstance(cmd, pus.InsertActivities):
                insert_seqs.add(header.request_id.seq_count)

    run = run_in_process(world, timeline, on_step=on_step)
    tm = received_telemetry(run.received, "the dry run's downlink")  # decoded once, by ground
    verifications = [(p.header.obt_s, p.report) for p in run.received if isinstance(p.report, pus.Verification)]
    rows = run.uploads[0].rows if run.uploads else ()
    result.commands = _outcomes(rows, verifications, insert_seqs, world.universe.oscillator.initial_offset_s,
                                world.epoch_utc)
    result.mode_path = [(t, e.from_mode.name, e.to_mode.name, e.cause) for t, e in tm.mode_changes]
    data = RunData(Path("."), world, Truth.from_records(run.truth), tm)
    result.figures, _ = score_run(data, case_requirements(world))
    return result


def case_requirements(world: Scenario) -> ReportConfig:
    """The scenario's requirements for one case, the peak body rate capped at what the case's geometry asks: the
    line-of-sight rate at C/A, speed over C/A distance (a 72 km flyby at 7 km/s never needs the paper's 7 deg/s)."""
    cfg = world.ground.report
    f = world.universe.flyby
    asked_deg_s = math.degrees(f.speed_km_s / f.ca_distance_km)
    return cfg.model_copy(update={"peak_rate_required_deg_s": min(cfg.peak_rate_required_deg_s, asked_deg_s)})


def _rehearse(args: tuple[Scenario, Timeline, FlybyBelief, Case, float | None, str]) -> CaseResult:
    return rehearse_case(*args)


def dry_run(sc: Scenario, timeline: Timeline, belief: FlybyBelief | None = None, jobs: int | None = 1,
            corners: bool = True, upload_utc_s: float | None = None, fidelity: str = "centroid") -> list[CaseResult]:
    """Every case of the dry run (ground's belief first, then its corners unless ``corners`` is False), ``jobs``
    cases at a time in separate processes (None: one per core, at most one per case; more than the cores cost more
    processor time in switching than they gain in packing, measured on two cores); ``upload_utc_s`` and
    ``fidelity`` as in ``rehearsal_scenario``."""
    belief = compose.ground_belief(sc) if belief is None else belief
    todo = [(sc, timeline, belief, c, upload_utc_s, fidelity) for c in (cases() if corners else cases()[:1])]
    jobs = min(len(todo), os.cpu_count() or 1) if jobs is None else jobs
    if jobs <= 1:
        return [_rehearse(t) for t in todo]
    from obsw import kernels
    from universe import kernels as universe_kernels

    kernels.warm_up()  # loaded once here (0.4 s a process from Numba's cache), not in each worker forked from here
    universe_kernels.warm_up(camera=fidelity == "image")
    if sc.ground.upload_bad_pixel_map:
        compose.ground_bad_pixel_map(sc)  # the cases' one calibration, cached here before the workers fork
    # OpenCV's thread pool does not survive a fork: a child reconfiguring it (each case's universe sets one thread)
    # waits forever on the idle threads of a pool this process ran; with one thread here there is none to copy
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ProcessPoolExecutor(max_workers=min(jobs, len(todo))) as pool:
            return list(pool.map(_rehearse, todo))
    finally:
        cv2.setNumThreads(threads)


def _command_text(timeline: Timeline, row: int) -> str:
    cmd = timeline.entries[row - 1].command
    return " ".join([cmd.name, *(f"{k}={v}" for k, v in cmd.args.items())])


def _vs_ca(seconds: float) -> str:
    return f"C/A{round(seconds, 1) + 0.0:+.1f} s"  # + 0.0: no "-0.0"


def case_lines(r: CaseResult, timeline: Timeline, sc: Scenario, number: str) -> list[str]:
    """One case as text: its truth, each command's fate, the mode path and the requirements."""
    offset = sc.ground.a_priori_obt_offset_s
    head = (f"case {number}, {r.case.name} ({r.case.description()}): true C/A {r.true_ca_utc_s:.3f} s after the "
            f"epoch, {r.true_ca_distance_km:.3f} km")
    if r.error is not None:
        return [head, f"  CANNOT RUN: {r.error}"]
    verdict = "PASS" if r.ok else "FAIL"
    lines = [f"{head}: {verdict}"]
    table = [("row", "command", "uploaded for", "release OBT s", "release UTC", "vs true C/A", "outcome")]
    for c in r.commands:
        tag = f"OBT {c.uploaded_obt_s:.3f} s" if c.ca_offset_s is None else f"{_vs_ca(c.ca_offset_s)} (ground's C/A)"
        rel = "-" if c.release_obt_s is None else _vs_ca(c.release_obt_s - offset - r.true_ca_utc_s)
        table.append((str(c.row), _command_text(timeline, c.row), tag,
                      "-" if c.release_obt_s is None else f"{c.release_obt_s:.3f}", c.release_utc or "-", rel,
                      ("executed" + (" LATE: uploaded after its time, released on arrival" if c.late else ""))
                      if c.ok else f"REFUSED: {c.refused}"))
    width = [max(len(x[i]) for x in table) for i in range(len(table[0]))]
    lines += ["  " + "  ".join(x.ljust(w) for x, w in zip(row, width, strict=True)).rstrip() for row in table]
    path = " -> ".join(f"{to} ({cause}, {_vs_ca(t - offset - r.true_ca_utc_s)})" for t, _, to, cause in r.mode_path)
    first = r.mode_path[0][1] if r.mode_path else "STANDBY"
    lines.append(f"  modes: {first}" + (f" -> {path}" if path else " throughout"))
    if r.figures is not None:
        lines += [f"  {x}" for x in r.figures.summary_lines()]
    return lines


def verdict_lines(results: Sequence[CaseResult], timeline: Timeline) -> list[str]:
    """The dry run's verdict: PASS, or every refused row and failed case named."""
    bad_rows = sorted({c.row for r in results for c in r.commands if not c.ok})
    failed = [r.case.name for r in results if not r.ok]
    late = sorted({c.row for r in results for c in r.commands if c.late})
    warnings = [f"  WARNING: row {row} ({_command_text(timeline, row)}) uploaded after its time in "
                f"{sum(any(c.row == row and c.late for c in r.commands) for r in results)} of {len(results)} cases: "
                "released on arrival, later than meant" for row in late]
    if not failed:
        return [f"PASS: every command accepted and executed, every requirement holds, in all {len(results)} cases",
                *warnings]
    out = ["FAIL:", *warnings]
    for row in bad_rows:
        where = [r.case.name for r in results if any(c.row == row and not c.ok for c in r.commands)]
        out.append(f"  row {row} ({_command_text(timeline, row)}) refused or not executed in {len(where)} of "
                   f"{len(results)} cases: {', '.join(where)}")
    for r in results:
        if r.error is not None:
            out.append(f"  case {r.case.name}: cannot run: {r.error}")
        elif r.figures is not None and not r.figures.all_pass:
            out.append(f"  case {r.case.name}: requirements: {r.figures.summary_lines()[-1].split(': ', 1)[1]}")
    return out


def report_lines(results: Sequence[CaseResult], timeline: Timeline, sc: Scenario, belief: FlybyBelief,
                 source: str, upload_utc_s: float | None = None, fidelity: str = "centroid") -> list[str]:
    """The whole dry run as text: what ground believes, each case, the verdict."""
    g = sc.ground
    upload = g.upload_nominal_at_s if g.upload_nominal_at_s is not None else sc.universe.start_s
    upload = upload if upload_utc_s is None else upload_utc_s
    lines = [
        f"dry run of {source} for scenario {sc.name}: ground believes C/A at {utc_text(sc.epoch_utc, belief.ca_utc_s)} "
        f"({belief.ca_utc_s:.3f} s after the epoch) +- {belief.ca_time_sigma_s:g} s, {belief.ca_distance_km:.3f} km "
        f"+- {belief.ca_distance_sigma_km:g} km; on-board time by its a-priori correlation (OBT = UTC + "
        f"{g.a_priori_obt_offset_s:.3f} s); upload at {upload:g} s, light time {g.link.one_way_light_time_s:g} s, "
        f"margin {g.upload_margin_s:g} s; {fidelity}-level fidelity",
    ]
    for i, r in enumerate(results, start=1):
        lines += case_lines(r, timeline, sc, f"{i}/{len(results)}")
    return lines + verdict_lines(results, timeline)


def prepare(scenario_path: Path, timeline_path: Path, trajectory: Path | None) -> tuple[Scenario, Timeline,
                                                                                      FlybyBelief]:
    """The scenario, the timeline to rehearse (checked against the run) and ground's belief (the trajectory file's
    if given); raises DryRunInputError naming the file and what is wrong."""
    from ground.operator import OperatorError, believed_trajectory
    from scenario.model import load_scenario, timeline_checks
    from timeline.model import TimelineError
    from timeline.parse import load_timeline

    try:
        sc = load_scenario(scenario_path)
    except ScenarioError as err:
        raise DryRunInputError([f"{err.source}: {p}" for p in err.problems]) from None
    try:
        timeline = load_timeline(timeline_path)
    except TimelineError as err:
        raise DryRunInputError([f"{err.source}: {p}" for p in err.problems]) from None
    errors, _ = timeline_checks(sc, timeline)
    if errors:
        raise DryRunInputError([f"{timeline_path}: {p}" for p in errors])
    belief = compose.ground_belief(sc)
    if trajectory is not None:
        try:
            belief = believed_trajectory(trajectory.read_bytes(), belief, sc.epoch_utc)
        except (OSError, OperatorError) as exc:
            raise DryRunInputError([f"{trajectory}: {exc}"]) from None
    return sc, timeline, belief


def run_dry_run(scenario_path: Path, timeline_path: Path, trajectory: Path | None = None, jobs: int | None = 1,
                upload_utc_s: float | None = None, fidelity: str = "centroid", stream: Any = None) -> int:
    """Prepare, run and print a dry run; return its exit code (0 pass, 4 a refusal or a failed requirement,
    2 unusable input)."""
    import sys

    from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK

    stream = sys.stdout if stream is None else stream
    try:
        sc, timeline, belief = prepare(scenario_path, timeline_path, trajectory)
    except DryRunInputError as err:
        for p in err.problems:
            print(f"flyby ground --dry-run: {p}", file=sys.stderr)
        return EXIT_CONFIG
    results = dry_run(sc, timeline, belief, jobs=jobs, upload_utc_s=upload_utc_s, fidelity=fidelity)
    for line in report_lines(results, timeline, sc, belief, str(timeline_path), upload_utc_s, fidelity):
        print(line, file=stream, flush=True)
    return EXIT_OK if all(r.ok for r in results) else EXIT_CHECK_FAILED
