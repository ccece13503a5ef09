"""``flyby replay RUN``: feed a recorded run's flight-software inputs, open loop, to the flight software as installed
now, and compare its commanded torques and telemetry with the recorded ones.

The regression check of a flight-software change against recorded flybys (nominal, worst cases, fault campaigns):
an unchanged build gives the same replies, bit for bit; a changed one gets a diff by packet type, parameter and time
(first divergence, largest difference) as text and as an HTML page. ``--set obsw.PATH=VALUE`` replays with a
changed on-board configuration instead (a gain, a threshold), without editing any file.

Camera frames kept by reference (the default) are rendered again from the recorded scenario and the truth at their
exposure (``flyby.recorded_frames``) and checked against their recorded digests; raw ones are read from the record.
"""

from __future__ import annotations

import argparse
import html
import io
import sys
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from analysis.page import _CSS, _table
from analysis.stepdiff import StepDiff
from contracts import sdls
from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CHECK_FAILED, EXIT_CONFIG, EXIT_OK
from contracts.steplog import STEP_RECORD, StepLog, StepLogError
from flyby.recorded_frames import FrameMismatch, RecordedFrames, RecordedFramesError
from obsw.config import ObswConfig
from obsw.software import FlightSoftware
from obsw.tc_security import COUNTER_MAX, TcSecurity
from scenario.model import Scenario, load_scenario


class ReplayInputError(ValueError):
    """A replay cannot start: no record, or a configuration change that does not apply."""


@dataclass
class Replay:
    """What a replay found: the comparison, the torque histories, and how the replay went."""

    record: Path
    header: dict[str, Any]
    changes: list[str]
    diff: StepDiff
    obt_s: list[float] = field(default_factory=list)
    recorded_torque_nm: list[tuple[float, ...]] = field(default_factory=list)
    replayed_torque_nm: list[tuple[float, ...]] = field(default_factory=list)
    replayed_steps: int = 0
    rendered_frames: int = 0  # frames kept by reference, rendered again and found identical
    unanswered_steps: int = 0  # recorded requests whose reply the record lacks (a run cut short)
    truncated: bool = False
    crash: str | None = None  # the flight software raised: where and what
    authentication: str = ""  # how uplinked telecommands were authenticated in the replay

    @property
    def identical(self) -> bool:
        """Every reply the same as recorded, and the replay ran to the end of the record."""
        return self.diff.identical and self.crash is None


def record_path(run: Path) -> Path:
    """The step record of a run folder (or the record file itself)."""
    return run if run.is_file() else run / STEP_RECORD


def changed_config(recorded: dict[str, Any], changes: Sequence[str]) -> ObswConfig:
    """The recorded on-board configuration with ``changes`` (``PATH=VALUE``, PATH dotted inside ``obsw``,
    VALUE read as YAML) applied; ReplayInputError names the change or field at fault."""
    data = yaml.safe_load(yaml.safe_dump(recorded))  # a deep copy of plain values
    for change in changes:
        path, sep, text = change.partition("=")
        parts = path.strip().removeprefix("obsw.").split(".")
        if not sep or not all(parts):
            raise ReplayInputError(f"--set {change!r}: expected PATH=VALUE, e.g. control.kp_nm_per_rad=0.3")
        node = data
        for i, part in enumerate(parts[:-1]):
            if not isinstance(node.get(part), dict):
                raise ReplayInputError(f"--set {change!r}: obsw.{'.'.join(parts[:i + 1])} is not a section")
            node = node[part]
        if parts[-1] not in node:
            raise ReplayInputError(f"--set {change!r}: obsw.{'.'.join(parts)} is not an on-board setting")
        node[parts[-1]] = yaml.safe_load(text)
    try:
        return ObswConfig.model_validate(data)
    except ValidationError as exc:
        e = exc.errors()[0]
        where = ".".join(str(p) for p in e["loc"])
        raise ReplayInputError(f"obsw.{where}: {e['msg']}") from None


class RecordedSecurity(TcSecurity):
    """The telecommand authentication of a replay without the run's keys (they are never kept): each check returns
    the recorded outcome of the same check, in order, after making sure the unit is the one recorded."""

    def __init__(self) -> None:
        super().__init__(None)
        self.pending: deque[bytes | sdls.SecurityRejection] = deque()

    def check(self, unit: bytes) -> bytes:
        """The recorded outcome of the next check (the TC passed, or its rejection, counted as on board)."""
        if not self.pending:
            raise ReplayInputError(f"the replayed software checks an uplinked unit of {len(unit)} octets that the "
                                   "recording has no authentication outcome for")
        verdict = self.pending.popleft()
        if isinstance(verdict, sdls.SecurityRejection):
            self.rejected[verdict.failure_code] = min(self.rejected[verdict.failure_code] + 1, COUNTER_MAX)
            raise verdict
        if verdict not in unit:  # the unit is the TC packet between its security header and MAC
            raise ReplayInputError("an uplinked unit does not carry the TC packet its recorded check passed")
        return verdict

    def install(self, spi: int, wrapped_key: bytes) -> None:
        """Rekeying needs the keys; the recorded outcomes already carry its effect."""


def replay_security(header: dict[str, Any], keys: sdls.KeyRing | None) -> tuple[TcSecurity, str]:
    """The authentication a replay runs with, and how it was chosen: ``keys`` if given, the keys an in-process run
    derives from its seed, else the recorded outcomes of every check."""
    if keys is not None:
        return TcSecurity(keys), "the given key file"
    seed = (header.get("scenario") or {}).get("seed")
    if header.get("tc_keys") == "derived from the seed" and isinstance(seed, int):
        return TcSecurity(sdls.KeyRing.derived(seed)), "the keys derived from the seed (an in-process run)"
    return RecordedSecurity(), "the recorded outcomes of the checks (the run's keys are not kept)"


def replay(run: Path, obsw: ObswConfig | None = None, changes: Sequence[str] = (),
           scenario: Scenario | None = None, keys: sdls.KeyRing | None = None) -> Replay:
    """Replay a run's record (``run``: its folder or the record file) through ``FlightSoftware``, built from
    ``obsw`` if given, else from the recorded configuration with ``changes`` applied; frames kept by reference are
    rendered from ``scenario`` if given, else from the recorded one. Raises FrameMismatch at the first frame that
    renders differently from the recorded one, RecordedFramesError if one cannot be rendered."""
    path = record_path(run)
    log = StepLog(path)
    if obsw is None:
        obsw = changed_config(log.header.get("obsw", {}), changes)
    fsw = FlightSoftware(obsw)
    fsw.security, how = replay_security(log.header, keys)
    frames = RecordedFrames(path, log.header, scenario)
    out = Replay(path, log.header, list(changes), StepDiff())
    out.authentication = how
    for st, frame in frames.with_pixels(log.steps()):
        req = st.request
        if isinstance(fsw.security, RecordedSecurity):
            fsw.security.pending.extend(st.verdicts)
        out.rendered_frames += st.frame_digest is not None
        try:
            reply = fsw.step(req, frame)
        except ReplayInputError:  # the record does not fit the replay: unusable input, not a finding
            raise
        except Exception as exc:  # noqa: BLE001 - a changed build that raises is a finding, reported as one
            out.crash = (f"step {req.step}, OBT {req.obt_s:.3f} s: the flight software raised "
                         f"{type(exc).__name__}: {exc}")
            break
        fsw.take_log()
        out.replayed_steps += 1
        if st.reply is None:
            out.unanswered_steps += 1
            continue
        out.diff.compare(req.step, req.obt_s, st.reply, reply)
        out.obt_s.append(req.obt_s)
        out.recorded_torque_nm.append(st.reply.wheel_torque_nm)
        out.replayed_torque_nm.append(reply.wheel_torque_nm)
    out.truncated = log.truncated
    return out


def summary_lines(r: Replay) -> list[str]:
    """What the replay found, as printed and at the top of the text and HTML files."""
    h = r.header
    sc = h.get("scenario")  # format 1 recorded the scenario's name and seed, format 2 the whole scenario
    name, seed = (sc.get("name", "?"), sc.get("seed", "?")) if isinstance(sc, dict) else (sc or "?", h.get("seed", "?"))
    build = "the flight software as installed now" + (f", with {', '.join(r.changes)}" if r.changes else "")
    span = f"OBT {r.obt_s[0]:.3f}..{r.obt_s[-1]:.3f} s" if r.obt_s else "no step"
    lines = [f"replay of {r.record} (scenario {name}, seed {seed}): {r.replayed_steps} control periods ({span}) "
             f"through {build}"]
    if r.authentication:
        lines.append(f"telecommand authentication: {r.authentication}")
    if r.rendered_frames:
        lines.append(f"{r.rendered_frames} camera frames kept by reference rendered again, each identical to the "
                     "recorded one (BLAKE2b-64 of its pixels)")
    if r.truncated or r.unanswered_steps:
        lines.append(f"the record ends early: {r.unanswered_steps} request(s) without a recorded reply"
                     + (", the file cut inside a record" if r.truncated else ""))
    if r.crash:
        lines.append(f"CRASH: {r.crash}")
    if r.identical:
        lines.append(f"IDENTICAL: every commanded torque, frame request and telemetry packet of the "
                     f"{r.diff.steps} periods is the same as recorded")
        return lines
    rows = r.diff.rows()
    packets = sorted({p.packet for p in rows})
    lines.append(f"DIFFERENT: {r.diff.differing_steps} of {r.diff.steps} periods differ; {len(rows)} parameter(s) "
                 f"of {len(packets)} packet type(s)")
    first = r.diff.first()
    if first is not None:
        lines.append(f"first divergence: {first.packet} {first.parameter} at {first.first_text()}")
    return lines


def table_rows(r: Replay) -> list[tuple[str, str, int, str, str]]:
    """One row per differing parameter: packet type, parameter, differing samples, first divergence, largest."""
    return [(p.packet, p.parameter, p.count, p.first_text(), p.largest_text()) for p in r.diff.rows()]


TABLE_HEAD = ("packet type", "parameter", "differing samples", "first divergence (recorded -> replayed)",
              "largest difference")


def text_report(r: Replay) -> str:
    """The replay's finding and its table as plain text."""
    out = io.StringIO()
    for line in summary_lines(r):
        print(line, file=out)
    rows = table_rows(r)
    if rows:
        width = [max(len(str(x[i])) for x in [TABLE_HEAD, *rows]) for i in range(len(TABLE_HEAD))]
        for row in [TABLE_HEAD, *rows]:
            print("  ".join(str(c).ljust(w) for c, w in zip(row, width, strict=True)).rstrip(), file=out)
    return out.getvalue()


def _torque_png(r: Replay) -> bytes | None:
    """Replayed minus recorded wheel torque over OBT, one line per wheel (None if they never differ)."""
    if not r.obt_s:
        return None
    rec, rep = np.asarray(r.recorded_torque_nm, dtype=float), np.asarray(r.replayed_torque_nm, dtype=float)
    if rec.shape != rep.shape or not np.any(rec != rep):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(r.obt_s) - r.obt_s[0]
    fig, ax = plt.subplots(figsize=(9, 3.5), dpi=100)
    for w in range(rec.shape[1]):
        ax.plot(t, 1e3 * (rep[:, w] - rec[:, w]), lw=0.8, label=f"wheel {w}")
    ax.set_xlabel(f"OBT - {r.obt_s[0]:.3f} s")
    ax.set_ylabel("replayed - recorded torque, mN m")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def html_report(r: Replay) -> str:
    """The replay's finding as a self-contained HTML page: summary, table, torque difference plot."""
    import base64

    verdict = '<p class="pass">IDENTICAL</p>' if r.identical else '<p class="fail">DIFFERENT</p>'
    body = [f"<h1>Replay of {html.escape(str(r.record))}</h1>", verdict,
            "<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in summary_lines(r)) + "</ul>"]
    rows = table_rows(r)
    if rows:
        body += ["<h2>Differences by packet type and parameter</h2>", _table(TABLE_HEAD, rows, "differences")]
    png = _torque_png(r)
    if png is not None:
        body += ["<h2>Commanded wheel torques</h2>",
                 f'<img alt="torque difference" src="data:image/png;base64,{base64.b64encode(png).decode()}">']
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Replay</title><style>{_CSS}</style></head>"
            f"<body>{''.join(body)}</body></html>\n")


def cmd_replay(args: argparse.Namespace) -> int:
    """Replay a run, print the finding, write replay.txt and replay.html; exit 0 identical, 4 different, 2 no
    usable record or a frame that renders differently from the recorded one."""
    try:
        scenario = None if args.scenario is None else load_scenario(args.scenario)
    except ScenarioError as err:
        print(f"flyby replay: {err.source}: invalid scenario", file=sys.stderr)
        for line in err.problems:
            print(f"  {line}", file=sys.stderr)
        return EXIT_CONFIG
    try:
        keys = None if args.keys is None else sdls.load_key_file(args.keys)
    except sdls.KeyFileError as exc:
        print(f"flyby replay: --keys: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    try:
        result = replay(args.run, changes=args.set, scenario=scenario, keys=keys)
    except (StepLogError, ReplayInputError, RecordedFramesError, FrameMismatch) as exc:
        print(f"flyby replay: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    text = text_report(result)
    sys.stdout.write(text)
    out = args.out if args.out is not None else (args.run if args.run.is_dir() else args.run.parent) / "replay"
    out.mkdir(parents=True, exist_ok=True)
    (out / "replay.txt").write_text(text, encoding="utf-8")
    (out / "replay.html").write_text(html_report(result), encoding="utf-8")
    print(f"written: {out / 'replay.txt'}, {out / 'replay.html'}")
    return EXIT_OK if result.identical else EXIT_CHECK_FAILED


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``flyby replay`` on the CLI's sub-parsers."""
    p = sub.add_parser("replay", help="replay a recorded run through the flight software as installed now and diff "
                       "its torques and telemetry (exit 0 identical, 4 different, 2 unusable record or a frame "
                       "that renders differently)", description=__doc__)
    p.add_argument("run", type=Path, help=f"run folder (with its {STEP_RECORD}) or the record file")
    p.add_argument("--set", action="append", default=[], metavar="PATH=VALUE",
                   help="replay with this on-board setting changed, e.g. control.kp_nm_per_rad=0.3 (repeatable)")
    p.add_argument("--scenario", type=Path, default=None, metavar="FILE",
                   help="render the frames the record keeps by reference from this scenario instead of the recorded "
                   "one (a recorded scenario this build no longer reads)")
    p.add_argument("--keys", type=Path, default=None, metavar="FILE",
                   help="the run's telecommand key file (flyby run --keys FILE): authenticate the uplink for real "
                   "instead of taking the recorded outcomes of the checks")
    p.add_argument("--out", type=Path, default=None, help="folder for replay.txt and replay.html (default RUN/replay)")
    p.set_defaults(func=cmd_replay)
