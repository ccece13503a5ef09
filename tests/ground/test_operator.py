"""Operator requests become the right telecommands, and bad ones are refused with the field named."""

from __future__ import annotations

import pytest
import yaml

from contracts import pus
from scenario.model import scenario_from_dict
from ground.operator import OperatorError, command_request, timeline_request, trajectory_request
from scenario import compose


def _cmd(name: str, **args: object) -> bytes:
    return yaml.safe_dump({"command": name, "args": args}).encode()


def test_dictionary_command() -> None:
    """set_mode SAFE becomes TC[200,1] with mode SAFE."""
    tc = command_request(_cmd("set_mode", mode="SAFE"))
    assert isinstance(tc, pus.SetMode) and tc.mode == pus.Mode.SAFE


@pytest.mark.parametrize(("payload", "message"), [
    (_cmd("set_mode", mode="WARP"), "mode"),
    (_cmd("fly"), "unknown command 'fly'"),
    (_cmd("schedule_time_shift", delta_s="soon"), "delta_s must be a number"),
    (_cmd("schedule_delete"), "request_ids: required"),
    (_cmd("schedule_delete", request_ids=[-1]), "request_ids: must be"),
    (b"command: [", "not valid YAML"),
])
def test_bad_commands_are_refused(payload: bytes, message: str) -> None:
    """Each bad request is refused with a message naming what is wrong."""
    with pytest.raises(OperatorError, match=message):
        command_request(payload)


def test_schedule_requests() -> None:
    """Schedule requests become the PUS 11 telecommands with the operator's request ids."""
    shift = command_request(_cmd("schedule_time_shift", delta_s=2.5, request_ids=[4, 5]), apid=0x0C1)
    assert isinstance(shift, pus.TimeShiftActivities) and shift.delta_s == 2.5
    assert [r.seq_count for r in shift.request_ids or ()] == [4, 5]
    assert isinstance(command_request(_cmd("schedule_delete", request_ids=[7])), pus.DeleteActivities)
    assert isinstance(command_request(_cmd("schedule_report", detail=True)), pus.DetailReportRequest)
    assert isinstance(command_request(_cmd("schedule_report")), pus.SummaryReportRequest)
    # each encodes as a valid packet
    for tc in (shift, command_request(_cmd("ping"))):
        header, back = pus.decode_tc(pus.encode_tc(tc, 0x0C1, 1))
        assert back == tc


def test_trajectory_upload_uses_the_correlation() -> None:
    """A trajectory at C/A = 170 s UTC is uploaded at OBT = correlation(170 s)."""
    seg = compose.ground_segment(scenario_from_dict({"name": "x"}))
    tc = trajectory_request(yaml.safe_dump({"ca_time_s": 170.0, "ca_distance_km": 54.0}).encode(), seg)
    assert tc.ca_obt_s == pytest.approx(seg.correlation.to_obt(170.0))
    assert tc.ca_distance_km == 54.0
    with pytest.raises(OperatorError, match="exactly one of"):
        trajectory_request(yaml.safe_dump({"ca_distance_km": 54.0}).encode(), seg)


def test_timeline_upload_refuses_late_absolute_commands_and_warns_of_late_ca_relative_ones() -> None:
    """A timeline with commands too late for the light time: the one on an absolute tag is refused, the one tied to C/A
    is uploaded all the same (the spacecraft releases it on arrival); a WARNING line names each."""
    seg = compose.ground_segment(scenario_from_dict({"name": "x"}))
    now_obt = seg.correlation.to_obt(0.0)
    text = yaml.safe_dump({"commands": [
        {"time": "CA-300s", "command": "stop_imaging"},
        {"time": "CA-100s", "command": "start_imaging", "args": {"period_s": 1.0}},
        {"time": f"OBT {now_obt + 10.0}", "command": "set_mode", "args": {"mode": "STANDBY"}},
    ]}).encode()
    # at UTC 0 with 33.4 s light time, C/A-300 s (about -130 s) and OBT now + 10 s are already past on arrival
    inserts, notes = timeline_request(text, "t.yaml", seg, utc_s=0.0)
    assert [(type(i), len(i.activities)) for i in inserts] == [(pus.InsertCaRelativeActivities, 2)]
    assert [n.split(":")[0] for n in notes] == ["WARNING", "WARNING"]
    assert any("row 1" in n and "released on arrival" in n for n in notes)
    assert any("row 3" in n and "refused" in n for n in notes)


def test_timeline_upload_records_every_row() -> None:
    """Ground's upload record gives each row its resolved OBT (C/A + offset by the correlation), the sequence count
    of its telecommand in the insert, and for a row tied to C/A due before it can arrive, why it is late."""
    seg = compose.ground_segment(scenario_from_dict({"name": "x"}))
    text = yaml.safe_dump({"commands": [
        {"time": "CA-100s", "command": "start_imaging", "args": {"period_s": 1.0}},
        {"time": "CA-300s", "command": "stop_imaging"},
        {"time": "+5s", "command": "set_mode", "args": {"mode": "STANDBY"}},
    ]}).encode()
    inserts, _ = timeline_request(text, "t.yaml", seg, utc_s=0.0)
    (up,) = seg.uploads
    ca_obt = seg.correlation.to_obt(seg.nominal_ca_utc_s)
    assert up.utc_s == 0.0
    assert up.not_before_obt_s == pytest.approx(seg.correlation.to_obt(seg.cfg.link.one_way_light_time_s
                                                                       + seg.cfg.upload_margin_s))
    assert [r.row for r in up.rows] == [1, 2, 3]
    assert [r.command for r in up.rows] == ["start_imaging", "stop_imaging", "set_mode"]
    assert [r.ca_offset_s for r in up.rows] == [-100.0, -300.0, -295.0]
    assert [r.obt_s for r in up.rows] == pytest.approx([ca_obt - 100.0, ca_obt - 300.0, ca_obt - 295.0])
    assert [r.refused for r in up.rows] == [None, None, None]  # tied to C/A: uploaded, late ones released on arrival
    assert up.rows[0].late is None and up.rows[1].late and up.rows[2].late
    assert "row 2" in up.rows[1].late and "earliest allowed OBT" in up.rows[1].late
    (insert,) = inserts  # C/A-relative rows only: one mission-subservice insert
    seq_of_offset = {a.ca_offset_s: pus.request_id_of(a.tc_packet).seq_count for a in insert.activities}
    assert [r.seq_count for r in up.rows] == [seq_of_offset[r.ca_offset_s] for r in up.rows]
