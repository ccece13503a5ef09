"""PUS service 1 on board: which verification reports a telecommand gets, honouring the acknowledgement flags it
carries (ECSS-E-ST-70-41C: a success report only when its flag is set; a failure report always)."""

from __future__ import annotations

from collections.abc import Callable

from contracts import pus

Send = Callable[[pus.Verification, int], None]
"""Sends one verification report to a destination id."""


class TcVerification:
    """The verification reports of one telecommand, sent to its source."""

    def __init__(self, header: pus.TcHeader, send: Send) -> None:
        self.header = header
        self._send = send

    def _success(self, stage: pus.Stage, flag: pus.AckFlag) -> None:
        if self.header.ack_flags & flag:
            self._send(pus.Verification(stage=stage, request_id=self.header.request_id), self.header.source_id)

    def accepted(self) -> None:
        """TM[1,1] if asked for."""
        self._success(pus.Stage.ACCEPTANCE, pus.AckFlag.ACCEPTANCE)

    def started(self) -> None:
        """TM[1,3] if asked for."""
        self._success(pus.Stage.START, pus.AckFlag.START)

    def completed(self) -> None:
        """TM[1,7] if asked for."""
        self._success(pus.Stage.COMPLETION, pus.AckFlag.COMPLETION)

    def failed(self, stage: pus.Stage, code: int, reason: str) -> None:
        """The failure report of ``stage`` (TM[1,2], [1,4] or [1,8]), whatever the flags."""
        report = pus.Verification(stage=stage, request_id=self.header.request_id, failure_code=code,
                                  reason=reason.encode("utf-8")[:255].decode("utf-8", errors="ignore"))
        self._send(report, self.header.source_id)
