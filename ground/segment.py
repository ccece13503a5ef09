"""The ground segment core: what ground believes, what it uploads, and what it makes of the telemetry.

Pure: each ``step`` takes the UTC and the telemetry packets the antenna received and returns the telecommands
to radiate, the decoded packets for the archive, and log lines. Ground knows UTC only: it converts everything
it uploads to on-board time with its current OBT-UTC correlation, fitted from the service 9 time reports
(each stamped on board one light time before it arrived).

Ground verifies what it radiates: a telecommand whose acceptance report has not come back within the round-trip
light time, its transmission and ``verification_margin_s`` is re-sent with a new sequence count, up to
``max_resends`` times, then raised as an alarm. Every on-board event of ``alarm_severity`` or above raises an alarm
too. A log line opening with ``WARNING`` or ``ALARM`` (``SECURITY ALARM`` for the security ones) is for an operator's
attention; the alarms are kept in ``state.alarms`` and the archive's alarms table.
"""

from __future__ import annotations

from dataclasses import dataclass, field


from contracts import pus, sdls
from ground.config import FlybyBelief, GroundConfig
from ground.correlation import Correlation, CorrelationError, TimeReport, fitted_correlation
from ground.uplink import schedule_inserts
from timeline.convert import resolved_commands
from timeline.model import Timeline


SCHEDULED_SEQ_BASE = 0x2000  # TCs sent inside schedule inserts count from here, so the radiated counts stay gapless


@dataclass(frozen=True)
class ReceivedPacket:
    """One telemetry packet as ground received it: raw bytes, and its decoding or why it failed."""

    raw: bytes
    receipt_utc_s: float
    header: pus.TmHeader | None
    report: pus.TmReport | None
    error: str | None
    alarm: str | None = None  # an alarm this packet raised (security, or an on-board event's severity)


@dataclass(frozen=True)
class RowUpload:
    """What ground did with one timeline row at an upload: the release OBT it resolved, and the sequence count of
    the row's telecommand inside the schedule insert, or why it refused the row."""

    row: int
    command: str
    obt_s: float
    ca_offset_s: float | None
    seq_count: int | None
    refused: str | None
    late: str | None = None  # uploaded although due before it can arrive: released on arrival (C/A-relative)


@dataclass(frozen=True)
class TimelineUpload:
    """One upload of a timeline: when (UTC, s after the epoch), the earliest OBT ground allowed, and every row."""

    utc_s: float
    not_before_obt_s: float
    rows: tuple[RowUpload, ...]


@dataclass
class GroundState:
    """Counters and latest values that ground keeps between steps."""

    tc_seq: int = 0  # the next radiated TC's sequence count, 0 .. SCHEDULED_SEQ_BASE - 1
    scheduled_seq: int = SCHEDULED_SEQ_BASE  # the next scheduled TC's, SCHEDULED_SEQ_BASE .. MAX_SEQ_COUNT
    received: int = 0
    undecodable: int = 0
    time_reports: list[TimeReport] = field(default_factory=list)
    last_hk: pus.Housekeeping | None = None
    last_hk_obt_s: float | None = None
    nominal_sent: bool = False
    verifications_failed: int = 0
    sent_requests: set[pus.RequestId] = field(default_factory=set)  # every TC ground sent, scheduled ones included
    alarms: list[str] = field(default_factory=list)
    resends: int = 0


@dataclass
class _Awaited:
    """A radiated telecommand whose acceptance report has not come back yet."""

    command: pus.TcCommand
    sent_utc_s: float
    due_utc_s: float
    sends: int


class GroundSegment:
    """Ground's logic for one run."""

    def __init__(self, cfg: GroundConfig, belief: FlybyBelief, epoch_utc: str, timeline: Timeline | None = None,
                 keys: sdls.KeyRing | None = None, *, bad_pixel_map: pus.LoadBadPixelMap | None = None,
                 bad_pixels_found: int = 0) -> None:
        """``belief``: ground's nominal trajectory; ``epoch_utc``: UTC of time zero, for the timeline's UTC tags;
        ``keys``: the security associations that authenticate its TCs (none: TCs go out unsecured, and the
        spacecraft refuses them); ``bad_pixel_map``: the camera's bad-pixel map from ground's calibration, uploaded
        with the nominal trajectory (none: not uploaded), of ``bad_pixels_found`` pixels the calibration found."""
        self.cfg = cfg
        self.belief = belief
        self.bad_pixel_map = bad_pixel_map
        self.bad_pixels_found = bad_pixels_found
        self.epoch_utc = epoch_utc
        self.nominal_ca_utc_s, self.nominal_ca_km = belief.ca_utc_s, belief.ca_distance_km
        self.correlation = Correlation.exact(self.cfg.a_priori_obt_offset_s, 0.0)
        self.state = GroundState()
        self.timeline = timeline
        self._queue: list[pus.TcCommand] = []
        self.uploads: list[TimelineUpload] = []
        self._sender = None if keys is None else sdls.Sender(keys)
        self._next_spi = 1 + max((sa.spi for sa in keys.associations), default=0) if keys is not None else 1
        self._rekeys: dict[pus.RequestId, sdls.SecurityAssociation] = {}  # rekeying TC -> the association it loads
        self._new_sa: dict[int, sdls.SecurityAssociation] = {}
        self.radiated: list[bytes] = []  # the TC packets of the last step's uplink, without their security envelope
        self._awaited: dict[pus.RequestId, _Awaited] = {}
        self._alarms_out: list[tuple[float, str]] = []  # alarms raised by no packet (verification), for the archive

    def nominal_trajectory_tc(self) -> pus.UploadNominalTrajectory:
        """The nominal trajectory telecommand, its C/A time in OBT by the current correlation."""
        b = self.belief
        return pus.UploadNominalTrajectory(
            ca_obt_s=self.correlation.to_obt(b.ca_utc_s),
            ca_distance_km=b.ca_distance_km,
            speed_km_s=b.speed_km_s,
            approach_direction=b.approach_direction,
            ca_direction=b.ca_direction,
            sigma_ca_time_s=b.ca_time_sigma_s,
            sigma_ca_distance_km=b.ca_distance_sigma_km,
        )

    @property
    def queued(self) -> int:
        """Telecommands waiting for the next step."""
        return len(self._queue)

    def queue(self, cmd: pus.TcCommand) -> None:
        """Send ``cmd`` at the next step (operator commands, timeline uploads)."""
        self._queue.append(cmd)

    def rekey(self) -> pus.RekeySecurityAssociation:
        """A rekeying TC with a fresh association, queued; ground switches to it when the spacecraft reports the TC
        completed (until then it keeps sending under the current one, which the spacecraft still accepts)."""
        if self._sender is None:
            raise ValueError("ground holds no TC keys to rekey")
        sa, wrapped = self._sender.new_association(self._next_spi)
        self._next_spi += 1
        self._new_sa[sa.spi] = sa
        cmd = pus.RekeySecurityAssociation(spi=sa.spi, wrapped_key=wrapped)
        self.queue(cmd)
        return cmd

    def _tc(self, cmd: pus.TcCommand, utc_s: float, sends: int = 1) -> bytes:
        """Encode ``cmd`` with the next sequence count, to be radiated at ``utc_s``, and await its acceptance."""
        packet = pus.encode_tc(cmd, self.cfg.apid, self._next_seq(), source_id=self.cfg.source_id)
        rid = pus.request_id_of(packet)
        sent = self.state.sent_requests
        sent.add(rid)
        if isinstance(cmd, pus.RekeySecurityAssociation):
            if cmd.spi in self._new_sa:
                self._rekeys[rid] = self._new_sa.pop(cmd.spi)
            else:  # a re-sent rekey: its completion switches ground as the first one's would have
                self._rekeys.update({rid: sa for sa in list(self._rekeys.values()) if sa.spi == cmd.spi})
        if isinstance(cmd, pus.InsertActivities | pus.InsertCaRelativeActivities):
            sent.update(a.request_id for a in cmd.activities)
        if isinstance(cmd, pus.AddEventActions):
            sent.update(pus.request_id_of(d.tc_packet) for d in cmd.definitions)
        link = self.cfg.link
        wait = (2.0 * link.one_way_light_time_s + len(packet) * 8.0 / link.uplink_rate_bps
                + self.cfg.verification_margin_s)
        self._awaited[rid] = _Awaited(cmd, utc_s, utc_s + wait, sends)
        return packet

    def _overdue(self, utc_s: float, log: list[str]) -> list[bytes]:
        """Re-send each telecommand whose acceptance is overdue (a new sequence count), or raise its alarm."""
        out = []
        for rid, a in list(self._awaited.items()):
            if utc_s < a.due_utc_s:
                continue
            del self._awaited[rid]
            what = f"TC {rid.seq_count} ({type(a.command).__name__}, sent at UTC {a.sent_utc_s:.1f} s)"
            if a.sends <= self.cfg.max_resends:
                packet = self._tc(a.command, utc_s, a.sends + 1)
                self.state.resends += 1
                log.append(f"WARNING: {what}: no acceptance report by UTC {a.due_utc_s:.1f} s: re-sent as TC "
                           f"{pus.request_id_of(packet).seq_count} (send {a.sends + 1} of {self.cfg.max_resends + 1})")
                out.append(packet)
            else:
                self._alarm(utc_s, f"ALARM: {what}: no acceptance report after {a.sends} send(s); given up", log)
        return out

    def _alarm(self, utc_s: float, text: str, log: list[str]) -> None:
        """An alarm that no packet raised."""
        self.state.alarms.append(text)
        self._alarms_out.append((utc_s, text))
        log.append(text)

    def take_alarms(self) -> list[tuple[float, str]]:
        """The alarms raised by no packet since the last call (UTC s, text), for the archive."""
        out, self._alarms_out = self._alarms_out, []
        return out

    @property
    def awaiting(self) -> int:
        """Radiated telecommands whose acceptance report has not come back yet."""
        return len(self._awaited)

    def step(self, utc_s: float, downlink: tuple[bytes, ...], arrival_utc_s: tuple[float, ...]
             ) -> tuple[list[bytes], list[ReceivedPacket], list[str]]:
        """Take the telemetry received by ``utc_s`` (each packet with its arrival UTC).

        Returns the telecommands to radiate now, the received packets, and log lines.
        """
        log: list[str] = []
        received = [self._receive(raw, t, log) for raw, t in zip(downlink, arrival_utc_s, strict=True)]
        uplink: list[bytes] = self._overdue(utc_s, log)
        upload_at = self.cfg.upload_nominal_at_s if self.cfg.upload_nominal_at_s is not None else float("-inf")
        if not self.state.nominal_sent and utc_s >= upload_at:
            self.state.nominal_sent = True
            tc = self.nominal_trajectory_tc()
            log.append(f"upload nominal trajectory: C/A {self.nominal_ca_utc_s:.2f} s UTC = OBT {tc.ca_obt_s:.2f} s, "
                       f"{self.nominal_ca_km:.2f} km")
            uplink.append(self._tc(tc, utc_s))
            uplink.append(self._tc(pus.SetTimeReportRate(rate_exponent=self.cfg.time_report_rate_exponent), utc_s))
            if self.bad_pixel_map is not None:
                m = self.bad_pixel_map
                log.append(f"upload bad-pixel map: {len(m.pixels)} pixel(s), {len(m.columns)} column(s)")
                if self.bad_pixels_found > len(m.pixels):
                    log.append(f"WARNING: the calibration found {self.bad_pixels_found} bad pixels; the map carries "
                               f"the {len(m.pixels)} that fit one telecommand (dead pixels first, then the brightest)")
                uplink.append(self._tc(m, utc_s))
            if self.timeline is not None and self.timeline.entries:
                inserts = self.timeline_upload(utc_s, tc, log)
                uplink += [self._tc(insert, utc_s) for insert in inserts]
                if inserts:
                    log.append(f"upload timeline: {sum(len(i.activities) for i in inserts)} of "
                               f"{len(self.timeline.entries)} command(s) into the on-board schedule")
        for cmd in self._queue:
            uplink.append(self._tc(cmd, utc_s))
        self._queue = []
        self.radiated = uplink
        units = uplink if self._sender is None else [self._sender.secure(p) for p in uplink]
        return units, received, log

    def timeline_upload(self, utc_s: float, nominal: pus.UploadNominalTrajectory, log: list[str],
                        timeline: Timeline | None = None) -> list[pus.InsertActivities | pus.InsertCaRelativeActivities]:
        """The schedule inserts of the timeline (``ground.uplink.schedule_inserts``), tags in OBT by the current
        correlation.

        A command that would reach the spacecraft too late (before now + light time + margin) is refused here if its
        tag is absolute; one tied to C/A is uploaded all the same (the spacecraft releases it on arrival, with an
        event: it was meant for before then, and the board may place C/A otherwise). Each is a WARNING line naming
        its row; empty if nothing is left. What happened to every row is appended to ``uploads``.
        """
        timeline = timeline or self.timeline
        assert timeline is not None
        source = self.cfg.timeline_file or "<timeline>"
        not_before = self.correlation.to_obt(utc_s + self.cfg.link.one_way_light_time_s + self.cfg.upload_margin_s)
        kw = dict(epoch_utc=self.epoch_utc, ca_utc_s=self.nominal_ca_utc_s, source=source)
        every = resolved_commands(timeline, self.correlation, **kw)
        why: dict[int, str] = {}
        late: dict[int, str] = {}
        for r in every:
            if r.obt_s >= not_before:
                continue
            text = (f"row {r.row}, field 'time': resolves to OBT {r.obt_s:.3f} s, before the earliest allowed OBT "
                    f"{not_before:.3f} s")
            if r.ca_offset_s is None:
                why[r.row] = text
                log.append(f"WARNING: timeline command refused: {text}")
            else:
                late[r.row] = text + ": uploaded, released on arrival"
                log.append(f"WARNING: timeline command late: {late[r.row]}")
        resolved = [r for r in every if r.row not in why]
        seqs: list[int] = []  # the sequence count of each resolved command's TC, in resolved order

        def next_seq() -> int:
            seqs.append(self._next_scheduled_seq())
            return seqs[-1]

        inserts = schedule_inserts(resolved, self.cfg.apid, next_seq, nominal, self.cfg.source_id)
        seq_of = {r.row: s for r, s in zip(resolved, seqs, strict=True)}
        self.uploads.append(TimelineUpload(utc_s, not_before, tuple(
            RowUpload(r.row, r.command.name, r.obt_s, r.ca_offset_s, seq_of.get(r.row), why.get(r.row), late.get(r.row))
            for r in sorted(every, key=lambda r: r.row))))
        return inserts

    def _next_seq(self) -> int:
        seq = self.state.tc_seq
        self.state.tc_seq = (seq + 1) % SCHEDULED_SEQ_BASE
        return seq

    def _next_scheduled_seq(self) -> int:
        seq = self.state.scheduled_seq
        self.state.scheduled_seq = SCHEDULED_SEQ_BASE + (seq + 1 - SCHEDULED_SEQ_BASE) % (
            pus.SEQ_COUNT_MODULO - SCHEDULED_SEQ_BASE)
        return seq

    def _receive(self, raw: bytes, utc_s: float, log: list[str]) -> ReceivedPacket:
        self.state.received += 1
        try:
            header, report = pus.decode_tm(raw)
        except pus.PacketError as exc:
            self.state.undecodable += 1
            log.append(f"undecodable telemetry packet ({len(raw)} octets): {exc}")
            return ReceivedPacket(raw, utc_s, None, None, str(exc))
        if isinstance(report, pus.TimeReport):
            # generated one light time plus its own transmission time before its last bit arrived
            delay = self.cfg.link.one_way_light_time_s + len(raw) * 8.0 / self.cfg.link.downlink_rate_bps
            self.state.time_reports.append(TimeReport(obt_s=report.obt_s, received_utc_s=utc_s, light_time_s=delay))
            self._refit(log)
        elif isinstance(report, pus.Housekeeping):
            self.state.last_hk, self.state.last_hk_obt_s = report, header.obt_s
        elif isinstance(report, pus.Verification) and report.success and report.stage == pus.Stage.COMPLETION \
                and report.request_id in self._rekeys and self._sender is not None:
            sa = self._rekeys.pop(report.request_id)
            self._sender.switch(sa)
            log.append(f"TC authentication: the spacecraft loaded security association {sa.spi}; sending under it")
        if isinstance(report, pus.Verification):
            self._awaited.pop(report.request_id, None)  # accepted or refused: it arrived
        if isinstance(report, pus.Verification) and not report.success:
            self.state.verifications_failed += 1
            log.append(f"WARNING: TC {report.request_id.seq_count} refused on board at {report.stage.name.lower()}: "
                       f"code 0x{report.failure_code:04X} {report.reason}")
        elif isinstance(report, pus.EventReport):
            log.append(f"event OBT {header.obt_s:.2f} s {type(report).__name__}: "
                       + ", ".join(f"{k}={v}" for k, v in report.model_dump().items() if k != "severity"))
            if isinstance(report, pus.ClockJumpEvent):
                self._clock_jumped(report.step_s, log)
        alarm = self._security_alarm(header, report) or self._event_alarm(header, report)
        if alarm is not None:
            self.state.alarms.append(alarm)
            log.append(alarm)
        return ReceivedPacket(raw, utc_s, header, report, None, alarm)

    def _security_alarm(self, header: pus.TmHeader, report: pus.TmReport) -> str | None:
        """A security alarm for a verification report of a TC ground never sent (someone else commanded the
        spacecraft, or tried to), or for a TC the spacecraft refused as unauthentic; None otherwise."""
        if isinstance(report, pus.Verification) and report.request_id not in self.state.sent_requests:
            rid = report.request_id
            outcome = "success" if report.success else f"failure 0x{report.failure_code:04X} {report.reason}"
            return (f"SECURITY ALARM: OBT {header.obt_s:.2f} s: {report.stage.name.lower()} {outcome} of TC APID "
                    f"0x{rid.apid:03X} sequence {rid.seq_count}, which ground never sent")
        if isinstance(report, pus.TcSecurityRejectedEvent):
            known = report.failure_code in pus.FailureCode._value2member_map_
            code = pus.FailureCode(report.failure_code).name if known else f"0x{report.failure_code:04X}"
            return (f"SECURITY ALARM: OBT {header.obt_s:.2f} s: the spacecraft refused an uplinked TC ({code}, SPI "
                    f"{report.spi}, ARSN {report.arsn})")
        return None

    def _event_alarm(self, header: pus.TmHeader, report: pus.TmReport) -> str | None:
        """An alarm for an on-board event of ``alarm_severity`` or above; None otherwise."""
        if not isinstance(report, pus.EventReport) or report.severity < pus.Severity[self.cfg.alarm_severity]:
            return None
        fields = ", ".join(f"{k}={v}" for k, v in report.model_dump(mode="json").items() if k != "severity")
        return f"ALARM: OBT {header.obt_s:.2f} s: {report.severity.name} event {type(report).__name__}: {fields}"

    def _clock_jumped(self, step_s: float, log: list[str]) -> None:
        """On-board time stepped by ``step_s`` (commanded or not): the time reports received so far were all stamped
        before it (the OBSW emits the event before its next report, and the link keeps order), so they are moved onto
        the new time scale and the fit goes on across the step instead of bending through it."""
        self.state.time_reports = [r.model_copy(update={"obt_s": r.obt_s + step_s}) for r in self.state.time_reports]
        log.append(f"time correlation: {len(self.state.time_reports)} earlier report(s) moved by the on-board "
                   f"time step of {step_s:+.6f} s")
        self._refit(log)

    def _refit(self, log: list[str]) -> None:
        reports = self.state.time_reports
        if len(reports) < 3:
            return
        try:
            self.correlation = fitted_correlation(reports[-self.cfg.correlation_window:])
        except CorrelationError as exc:
            log.append(f"time correlation not updated: {exc}")
