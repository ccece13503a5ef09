"""The ground node: the ground segment core on the bus, with the telemetry archive and the run's summary.

Every ``GroundStep`` from the universe brings the telemetry the antenna received and the truth of the
period; ground archives both, answers with the telecommands to radiate, and at the end of the run writes the
summary (and the report) into its output folder.
"""

from __future__ import annotations

import csv
import json
import logging
from pathlib import Path
from typing import IO

import numpy as np
import zenoh

from collections.abc import Callable

from contracts.bus import BusConfig, Keys
from contracts.clock import WallClock, process_usage
from contracts.errors import NodeFailure
from contracts.hoptrace import WORK_END, WORK_START, HopTrace
from contracts import pus
from contracts.messages import GroundReply, GroundStep, OperatorCommand, OperatorReply, TmLine, TruthRecord
from contracts.exitcodes import EXIT_OK
from contracts.runtime import Attachment
from contracts.truthtable import TruthTable
from ground.archive import Archive
from ground.operator import OperatorError, command_request, timeline_request, trajectory_request
from ground.segment import GroundSegment, ReceivedPacket

log = logging.getLogger("ground")
MAX_ALARM_LINES = 10  # alarms quoted in the summary (the archive keeps them all)
ATTENTION = ("SECURITY ALARM", "ALARM", "WARNING")  # ground's log lines that open so are logged as warnings


class TruthLog:
    """The universe's truth, one CSV row per control period, in the columns of ``contracts.truthtable``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._f: IO[str] = open(path, "w", newline="")
        self._w = csv.writer(self._f)
        self._table: TruthTable | None = None

    def add(self, rec: TruthRecord) -> None:
        """Append one record (the first one fixes the wheel count of the header)."""
        if self._table is None:
            self._table = TruthTable.for_record(rec)
            self._w.writerow(self._table.columns)
        self._w.writerow(self._table.cells(rec))

    def close(self) -> None:
        """Flush and close the file."""
        self._f.close()


def summary_lines(segment: GroundSegment, archive: Archive) -> list[str]:
    """What ground can tell at the end of a run, one line each: telemetry received and the time correlation
    (the requirement figures are the analysis's, added by whoever composed the node)."""
    lines = []
    counts = archive.counts()
    lines.append(f"telemetry: {counts.get('stored', 0)} packets archived, {segment.state.undecodable} undecodable, "
                 f"{len(archive.gaps())} sequence gap(s)")
    c = segment.correlation
    lines.append(f"time correlation: OBT - UTC offset {c.offset_s:+.4f} s, drift {c.drift_ppm:+.3f} ppm "
                 f"from {c.n_reports} time reports")
    alarms = segment.state.alarms
    if alarms:
        lines.append(f"{len(alarms)} alarm(s); the first {min(len(alarms), MAX_ALARM_LINES)}:")
        lines += alarms[:MAX_ALARM_LINES]
    return lines


def operator_request(segment: GroundSegment, msg: OperatorCommand, utc_s: float | None) -> OperatorReply:
    """Queue the telecommands of an operator request, or refuse it with the reason."""
    try:
        if msg.action == "send" and msg.name == "rekey":  # ground makes the key: the console never sees it
            try:
                segment.rekey()
            except ValueError as exc:
                raise OperatorError(str(exc)) from None
            return OperatorReply(request=msg.request, ok=True, text="queued RekeySecurityAssociation for the next "
                                 "uplink; ground sends under the new key once the spacecraft confirms it")
        if msg.action == "send":
            cmds = [command_request(msg.payload, segment.cfg.apid)]
            notes: list[str] = []
        elif msg.action == "upload_trajectory":
            cmds, notes = [trajectory_request(msg.payload, segment)], []
        else:
            if utc_s is None:
                raise OperatorError("the run has not started: no time to convert the timeline at")
            inserts, notes = timeline_request(msg.payload, msg.name, segment, utc_s)
            cmds = list(inserts)
    except OperatorError as exc:
        return OperatorReply(request=msg.request, ok=False, text=str(exc))
    for c in cmds:
        segment.queue(c)
    what = ", ".join(type(c).__name__ for c in cmds)
    return OperatorReply(request=msg.request, ok=True,
                         text=f"queued {what} for the next uplink" + ("; " + "; ".join(notes) if notes else ""))


def tm_line(p: ReceivedPacket) -> TmLine | None:
    """A line for people watching the run, for housekeeping, events and verification reports."""
    r, h = p.report, p.header
    if h is None or r is None:
        return None
    if isinstance(r, pus.Housekeeping):
        rate = float(np.degrees(np.linalg.norm(r.rate_rad_s)))
        err = "-" if r.pointing_error_rad is None else f"{np.degrees(r.pointing_error_rad):.3f} deg"
        best = "-" if r.best_ca_obt_s is None else f"C/A OBT {r.best_ca_obt_s:.2f} s at {r.best_ca_distance_km:.2f} km"
        text = f"{r.mode.name:<20} rate {rate:6.2f} deg/s  pointing error {err}  best {best}"
        return TmLine(utc_s=p.receipt_utc_s, obt_s=h.obt_s, kind="HK", text=text)
    if isinstance(r, pus.EventReport):
        fields = ", ".join(f"{k}={v}" for k, v in r.model_dump().items() if k != "severity")
        return TmLine(utc_s=p.receipt_utc_s, obt_s=h.obt_s, kind=f"EVENT {r.severity.name}",
                      text=f"{type(r).__name__}: {fields}")
    if isinstance(r, pus.Verification):
        status = "ok" if r.success else f"FAILED 0x{r.failure_code:04X} {r.reason}"
        return TmLine(utc_s=p.receipt_utc_s, obt_s=h.obt_s, kind="TC",
                      text=f"TC {r.request_id.seq_count} {r.stage.name.lower()} {status}")
    return None


def run(bus: Attachment, segment: GroundSegment, archive: Archive, truth: TruthLog, bus_cfg: BusConfig,
        tc_log: IO[bytes] | None = None) -> None:
    """Answer ground steps until the run ends."""
    last: tuple[int, GroundReply] | None = None
    answered: dict[int, OperatorReply] = {}
    last_status = -1.0
    wait = bus_cfg.startup_timeout_s + bus_cfg.reply_timeout_s
    while True:
        got = bus.receive(wait)
        if got is None:
            raise NodeFailure("universe", bus.sim_time_s, f"stopped sending ground steps (nothing for {wait:g} s)")
        msg = got.msg
        if isinstance(msg, OperatorCommand):
            reply = answered.get(msg.request)
            if reply is None:  # a console resends until answered: act on each request once
                reply = answered[msg.request] = operator_request(segment, msg, bus.sim_time_s)
                log.info("operator request %d (%s %s): %s", msg.request, msg.action, msg.name, reply.text)
            bus.publish(bus.keys.operator_reply, reply)
            continue
        if not isinstance(msg, GroundStep):
            continue
        wait = bus_cfg.reply_timeout_s
        if last is not None and msg.step <= last[0]:
            if msg.step == last[0]:
                bus.publish(bus.keys.ground_reply, last[1])
            continue
        bus.sim_time_s = msg.utc_s
        bus.mark(WORK_START, msg.step)
        uplink, received, lines = segment.step(msg.utc_s, msg.downlink, msg.downlink_utc_s)
        bus.mark(WORK_END, msg.step)
        # answer first: the universe goes on with its periods while this step's telemetry and truth are filed
        reply = GroundReply(step=msg.step, uplink=tuple(uplink))
        bus.publish(bus.keys.ground_reply, reply)
        last = (msg.step, reply)
        for p in received:
            stored = archive.store(p.raw, p.receipt_utc_s)
            if p.alarm is not None:
                archive.alarm(p.receipt_utc_s, p.alarm, stored.packet_id)
            line = tm_line(p)
            if line is not None:
                bus.publish(bus.keys.tm_lines, line)
        archive.flush()  # at most one ground step of telemetry is ever unwritten
        for rec in msg.truth:
            truth.add(rec)
        for utc, text in segment.take_alarms():
            archive.alarm(utc, text)
        for line in lines:
            (log.warning if line.startswith(ATTENTION) else log.info)("%s", line)
        if tc_log is not None and uplink:
            tc_log.write(b"".join(segment.radiated))  # every telecommand radiated (no security envelope), for analysis
            tc_log.flush()
        now = bus.clock.now()
        if now - last_status >= 0.5:
            hk = segment.state.last_hk
            bus.status(msg.utc_s, None, hk.mode.name if hk is not None else None,
                       text=f"{segment.state.received} TM packets")
            last_status = now


Finisher = Callable[[Path, list[str], bool], list[str]]
"""Called once the run folder is complete: (folder, ground's summary lines, whether the run ended normally) ->
the summary lines to keep (the composition adds the requirement figures and writes the report)."""


def main(conf: zenoh.Config, segment: GroundSegment, bus_cfg: BusConfig, run_id: str, out: Path,
         finish: Finisher | None = None, trace: Path | None = None) -> int:
    """Run the ground node until the run ends or a peer fails; return the process exit code. ``trace``: a file
    for the time marks of its exchanges with the universe (``contracts.hoptrace``)."""
    keys = Keys(run_id)
    archive = Archive(out / "archive.sqlite", tm_bin=out / "tm.bin")
    truth = TruthLog(out / "truth.csv")
    with zenoh.open(conf) as session:
        bus = Attachment(session, keys, "ground", WallClock(), log,
                         trace=None if trace is None else HopTrace("ground", trace))
        bus.subscribe(keys.ground_step, GroundStep)
        bus.subscribe(keys.operator, OperatorCommand)
        bus.watch_peers()
        bus.declare_alive()
        try:
            with open(out / "tc.bin", "wb") as tc_log:
                code, _ = bus.guarded(lambda: run(bus, segment, archive, truth, bus_cfg, tc_log))
        finally:
            bus.close()
    # whatever happened, keep what was received: write the summary, then close the archive
    truth.close()
    lines = summary_lines(segment, archive)
    archive.close()
    if code != EXIT_OK:
        lines.insert(0, "run ended early: the figures cover only what was received")
    (out / "summary.json").write_text(json.dumps({"lines": lines}, indent=2))
    c = segment.correlation
    (out / "correlation.json").write_text(json.dumps({
        "offset_s": c.offset_s, "drift": c.drift, "offset_sigma_s": c.offset_sigma_s,
        "drift_sigma_ppm": c.drift_sigma_ppm, "n_reports": c.n_reports, "residual_rms_s": c.residual_rms_s}, indent=2))
    if finish is not None:
        # the report reads the whole run back: its memory is the report's, apart from the run's own
        log.info("before the report, %s", process_usage().line())
        lines = finish(out, lines, code == EXIT_OK)
        (out / "summary.json").write_text(json.dumps({"lines": lines}, indent=2))
    for line in lines:
        log.info("%s", line)
    return code
