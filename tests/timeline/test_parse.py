"""Timeline files: every tag form, every bad input's message, and YAML/CSV round trips."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import Field

from contracts.model import Frozen
from timeline.model import (
    MODES,
    AfterPreviousTag,
    CaTag,
    Command,
    CommandDefinition,
    CommandError,
    ObtTag,
    Timeline,
    TimelineEntry,
    TimelineError,
    UtcTag,
    default_registry,
)
from timeline.parse import (
    TagError,
    load_timeline,
    tag_from_text,
    tag_text,
    timeline_csv_text,
    timeline_from_csv_text,
    timeline_from_yaml_text,
    timeline_yaml_text,
)

EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "timelines" / "flyby-imaging.yaml"
UTC = timezone.utc


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2022-09-26T23:10:24Z", UtcTag(utc=datetime(2022, 9, 26, 23, 10, 24, tzinfo=UTC))),
        ("2022-09-26T23:10:24.25Z", UtcTag(utc=datetime(2022, 9, 26, 23, 10, 24, 250000, tzinfo=UTC))),
        ("2022-09-27T01:10:24+02:00", UtcTag(utc=datetime(2022, 9, 26, 23, 10, 24, tzinfo=UTC))),
        ("OBT 1234.5", ObtTag(obt_s=1234.5)),
        ("OBT -12", ObtTag(obt_s=-12.0)),
        ("obt12s", ObtTag(obt_s=12.0)),
        ("OBT 1e3", ObtTag(obt_s=1000.0)),
        ("+12.5s", AfterPreviousTag(delay_s=12.5)),
        ("+3", AfterPreviousTag(delay_s=3.0)),
        ("+0s", AfterPreviousTag(delay_s=0.0)),
        ("CA-240s", CaTag(ca_offset_s=-240.0)),
        ("CA+60s", CaTag(ca_offset_s=60.0)),
        ("CA - 1.5 s", CaTag(ca_offset_s=-1.5)),
        ("CA", CaTag(ca_offset_s=0.0)),
    ],
)
def test_every_tag_form_reads_to_its_tag(text: str, expected: object) -> None:
    """Each documented tag text reads to the tag it denotes."""
    assert tag_from_text(text) == expected


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("CA*5", "cannot read 'CA*5' as a time tag (expected"),
        ("T-240", "cannot read 'T-240' as a time tag"),
        ("+-5s", "cannot read '+-5s'"),
        ("2022-13-26T23:10:24Z", "month must be in 1..12"),
        ("2022-09-26T23:10:24", "must carry its zone"),
        ("OBT 1e999", "must be a finite number"),
        ("", "cannot read '' as a time tag"),
    ],
)
def test_bad_tag_text_is_refused_with_its_reason(text: str, reason: str) -> None:
    """A tag that is malformed or impossible is refused with a message saying why."""
    with pytest.raises(TagError) as err:
        tag_from_text(text)
    assert reason in str(err.value)


finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12)
utc_datetimes = st.datetimes(
    min_value=datetime(2000, 1, 1), max_value=datetime(2100, 1, 1), timezones=st.just(UTC)
)
tags = st.one_of(
    st.builds(UtcTag, utc=utc_datetimes),
    st.builds(ObtTag, obt_s=finite),
    st.builds(AfterPreviousTag, delay_s=st.floats(min_value=0, max_value=1e9)),
    st.builds(CaTag, ca_offset_s=finite),
)


@given(tags)
@settings(max_examples=200)
def test_tag_text_reads_back_to_the_same_tag(tag: object) -> None:
    """tag_from_text(tag_text(t)) == t for every tag."""
    assert tag_from_text(tag_text(tag)) == tag  # type: ignore[arg-type]


def test_yaml_reads_every_tag_form_and_validates_arguments() -> None:
    """A YAML timeline with each tag form gives the entries, arguments coerced to their schema types."""
    text = """
description: all forms
commands:
  - {time: 2022-09-26T23:10:24Z, command: set_mode, args: {mode: ACQUISITION}}
  - {time: '2022-09-26T23:10:25.5Z', command: start_imaging, args: {period_s: 2}}
  - {time: OBT 100, command: stop_imaging}
  - {time: '+5s', command: set_camera_cadence, args: {period_s: 0.5, exposure_s: 0.01}}
  - {time: CA-240s, command: report_time}
  - {time: CA+60s, command: upload_nominal_trajectory, args: {ca_obt_s: 168, ca_distance_km: 55}}
"""
    tl = timeline_from_yaml_text(text)
    assert [e.tag for e in tl.entries] == [
        UtcTag(utc=datetime(2022, 9, 26, 23, 10, 24, tzinfo=UTC)),
        UtcTag(utc=datetime(2022, 9, 26, 23, 10, 25, 500000, tzinfo=UTC)),
        ObtTag(obt_s=100.0),
        AfterPreviousTag(delay_s=5.0),
        CaTag(ca_offset_s=-240.0),
        CaTag(ca_offset_s=60.0),
    ]
    assert [e.command for e in tl.entries] == [
        Command(name="set_mode", args={"mode": "ACQUISITION"}),
        Command(name="start_imaging", args={"period_s": 2.0}),
        Command(name="stop_imaging", args={}),
        Command(name="set_camera_cadence", args={"period_s": 0.5, "exposure_s": 0.01}),
        Command(name="report_time", args={"count": 1}),
        Command(name="upload_nominal_trajectory", args={"ca_obt_s": 168.0, "ca_distance_km": 55.0}),
    ]
    assert isinstance(tl.entries[1].command.args["period_s"], float)


def _yaml_problems(rows: str) -> list[str]:
    """The problems a YAML timeline with these command rows is refused with."""
    with pytest.raises(TimelineError) as err:
        timeline_from_yaml_text("commands:\n" + rows, "t.yaml")
    assert str(err.value).startswith("t.yaml: ")
    return err.value.problems


@pytest.mark.parametrize(
    ("rows", "expected"),
    [
        (
            "  - {time: CA, command: stop_imaging}\n  - {time: CA, command: fire_thruster}\n",
            "row 2, field 'command': unknown command 'fire_thruster' (known: adjust_obt, report_time, set_camera_cadence,",
        ),
        ("  - {time: CA, command: start_imaging, args: {period_s: -1}}\n", "row 1, field 'args.period_s': must be > 0"),
        ("  - {time: CA, command: start_imaging, args: {period_s: fast}}\n",
         "row 1, field 'args.period_s': must be a number, got 'fast' (str)"),
        ("  - {time: CA, command: set_mode}\n", "row 1, field 'args.mode': missing"),
        ("  - {time: CA, command: set_mode, args: {mode: WARP}}\n", "row 1, field 'args.mode': Input should be 'SAFE'"),
        ("  - {time: CA, command: stop_imaging, args: {period_s: 1}}\n",
         "row 1, field 'args.period_s': not an argument of this command"),
        ("  - {time: CA, command: set_camera_cadence, args: {period_s: 1, exposure_s: 2}}\n",
         "row 1, field 'args': exposure_s (2 s) must not exceed period_s (1 s)"),
        ("  - {time: CA, command: start_imaging, args: [1]}\n", "row 1, field 'args': must be a mapping"),
        ("  - {time: 'CA*5', command: stop_imaging}\n", "row 1, field 'time': cannot read 'CA*5' as a time tag"),
        ("  - {time: 12, command: stop_imaging}\n", "row 1, field 'time': a bare number (12) is ambiguous"),
        ("  - {time: 2022-09-26, command: stop_imaging}\n", "row 1, field 'time': a date alone (2022-09-26)"),
        ("  - {time: 2022-09-26T23:10:24, command: stop_imaging}\n", "row 1, field 'time': cannot read"),
        ("  - {time: '+5s', command: stop_imaging}\n",
         "row 1, field 'time': '+5s' is relative to the previous command, but there is none"),
        ("  - {time: CA, command: stop_imaging, when: now}\n", "row 1, field 'when': unknown field"),
        ("  - {command: stop_imaging}\n", "row 1, field 'time': missing"),
        ("  - {time: CA}\n", "row 1, field 'command': missing command name"),
        ("  - just text\n", "row 1: must be a mapping with 'time' and 'command', got str"),
    ],
)
def test_bad_yaml_row_names_row_and_field(rows: str, expected: str) -> None:
    """Each bad YAML row is refused with a message naming its row and field."""
    problems = _yaml_problems(rows)
    assert any(p.startswith(expected) for p in problems), problems


def test_naive_yaml_timestamp_is_refused_for_lack_of_zone() -> None:
    """An unquoted YAML timestamp without a zone is refused because UTC needs its zone."""
    problems = _yaml_problems("  - {time: 2022-09-26 23:10:24, command: stop_imaging}\n")
    assert problems == ["row 1, field 'time': cannot read '2022-09-26T23:10:24' as a time tag: "
                        "UTC time must carry its zone (end it in 'Z')"]


def test_every_bad_row_is_reported_in_one_pass() -> None:
    """All problems of a file are listed together, in row order."""
    problems = _yaml_problems(
        "  - {time: CA, command: nope}\n  - {time: CA, command: stop_imaging}\n  - {time: X, command: stop_imaging}\n"
    )
    assert [p.split(",")[0] for p in problems] == ["row 1", "row 3"]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("- {time: CA, command: stop_imaging}\n", "(file): must be a mapping with a 'commands' list, got list"),
        ("description: x\n", "field 'commands': missing"),
        ("commands: 3\n", "field 'commands': must be a list of commands, got int"),
        ("commands: []\nauthor: me\n", "field 'author': unknown field"),
        ("commands: [\n", "line 2, column 1: not valid YAML"),
    ],
)
def test_bad_yaml_file_names_the_fault(text: str, expected: str) -> None:
    """A YAML file of the wrong shape or syntax is refused with a message naming where."""
    with pytest.raises(TimelineError) as err:
        timeline_from_yaml_text(text)
    assert any(p.startswith(expected) for p in err.value.problems), err.value.problems


CSV_HEADER = "time,command,mode,period_s,exposure_s\n"


def test_csv_reads_rows_skipping_blank_lines() -> None:
    """A CSV timeline gives the same entries as its YAML twin; blank lines are skipped."""
    csv_text = (
        CSV_HEADER
        + "CA-240s,set_mode,ACQUISITION,,\n\n"
        + "+0s,start_imaging,,1,\n"
        + "2022-09-26T23:10:24Z , set_camera_cadence ,, 0.5 ,0.01\n"
    )
    yaml_text = """commands:
  - {time: CA-240s, command: set_mode, args: {mode: ACQUISITION}}
  - {time: '+0s', command: start_imaging, args: {period_s: 1}}
  - {time: 2022-09-26T23:10:24Z, command: set_camera_cadence, args: {period_s: 0.5, exposure_s: 0.01}}
"""
    assert timeline_from_csv_text(csv_text) == timeline_from_yaml_text(yaml_text)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (CSV_HEADER + "CA,set_mode,ACQUISITION,,\nCA,stop_imaging,,\n",
         "row 2 (line 3): has 4 cells, the header has 5"),
        (CSV_HEADER + "CA,start_imaging,,fast,\n",
         "row 1 (line 2), column 'period_s': Input should be a valid number, unable to parse string as a number, "
         "got 'fast'"),
        (CSV_HEADER + "CA,start_imaging,,0,\n", "row 1 (line 2), column 'period_s': must be > 0, got '0'"),
        (CSV_HEADER + "CA,stop_imaging,,1,\n", "row 1 (line 2), column 'period_s': not an argument of this command"),
        (CSV_HEADER + "CA,set_mode,,,\n", "row 1 (line 2), column 'mode': missing"),
        (CSV_HEADER + "CA,fire_thruster,,,\n", "row 1 (line 2), column 'command': unknown command 'fire_thruster'"),
        (CSV_HEADER + "CA,,,,\n", "row 1 (line 2), column 'command': missing command name"),
        (CSV_HEADER + "CA!,stop_imaging,,,\n", "row 1 (line 2), column 'time': cannot read 'CA!' as a time tag"),
        (CSV_HEADER + ",stop_imaging,,,\n", "row 1 (line 2), column 'time': missing"),
        (CSV_HEADER + "+1s,stop_imaging,,,\n", "row 1 (line 2), column 'time': '+1s' is relative to the previous"),
        (CSV_HEADER + "CA,set_camera_cadence,,1,2\n",
         "row 1 (line 2), argument columns: exposure_s (2 s) must not exceed period_s (1 s)"),
        ("\ntime,command,speed_m_s\n", "line 2, column 'speed_m_s': not an argument of any command"),
        ("time,mode\n", "line 1: missing column 'command'"),
        ("time,command,mode,mode\n", "line 1, column 'mode': repeated"),
        ("\n\n", "(file): empty, expected a header row"),
    ],
)
def test_bad_csv_names_row_line_and_column(text: str, expected: str) -> None:
    """Each bad CSV header or row is refused with a message naming its row, line and column."""
    with pytest.raises(TimelineError) as err:
        timeline_from_csv_text(text, "t.csv")
    assert any(p.startswith(expected) for p in err.value.problems), err.value.problems


def test_csv_saved_with_a_byte_order_mark_reads_normally(tmp_path: Path) -> None:
    """A CSV saved by a spreadsheet with a UTF-8 byte-order mark reads as without it."""
    text = CSV_HEADER + "CA-240s,set_mode,ACQUISITION,,\n"
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert load_timeline(path) == timeline_from_csv_text(text)
    assert timeline_from_csv_text("\ufeff" + text) == timeline_from_csv_text(text)


def test_csv_rows_count_commands_and_lines_count_the_file() -> None:
    """After blank lines, the row number counts commands and the line number counts file lines."""
    with pytest.raises(TimelineError) as err:
        timeline_from_csv_text(CSV_HEADER + "\nCA,stop_imaging,,,\n\n\nCA,nope,,,\n")
    assert err.value.problems[0].startswith("row 2 (line 6), column 'command': unknown command 'nope'")


# Valid commands of the standard registry, as (name, args) before validation.
periods = st.floats(min_value=1e-3, max_value=3600, allow_nan=False)
commands = st.one_of(
    st.builds(lambda m: ("set_mode", {"mode": m}), st.sampled_from(MODES)),
    st.builds(lambda p: ("start_imaging", {"period_s": p}), periods),
    st.just(("stop_imaging", {})),
    st.builds(
        lambda p, f: ("set_camera_cadence", {"period_s": p, "exposure_s": p * f}),
        periods,
        st.floats(min_value=1e-3, max_value=1.0),
    ),
    st.builds(
        lambda t, d: ("upload_nominal_trajectory", {"ca_obt_s": t, "ca_distance_km": d}),
        st.floats(min_value=0.0, max_value=1e9),
        st.floats(min_value=1e-3, max_value=1e6),
    ),
    st.builds(lambda n: ("report_time", {"count": n}), st.integers(1, 1000)),
)


@st.composite
def timelines(draw: st.DrawFn) -> Timeline:
    """Random valid timelines of the standard commands (never starting with a relative tag)."""
    reg = default_registry()
    n = draw(st.integers(0, 8))
    entries = []
    for i in range(n):
        tag = draw(tags.filter(lambda t: not isinstance(t, AfterPreviousTag)) if i == 0 else tags)
        name, args = draw(commands)
        entries.append(TimelineEntry(tag=tag, command=reg.command(name, args)))
    return Timeline(entries=tuple(entries))


@given(timelines())
@settings(max_examples=60, deadline=None)
def test_yaml_and_csv_writers_read_back_to_the_same_timeline(tl: Timeline) -> None:
    """Written as YAML or as CSV, any timeline reads back equal, so both formats give the same Timeline."""
    from_yaml = timeline_from_yaml_text(timeline_yaml_text(tl, description="round trip"))
    from_csv = timeline_from_csv_text(timeline_csv_text(tl))
    assert from_yaml == tl
    assert from_csv == tl


def test_example_file_loads_and_its_csv_twin_is_equal(tmp_path: Path) -> None:
    """The shipped flyby-imaging timeline loads, is all C/A-tied, and its CSV form loads to the same Timeline."""
    tl = load_timeline(EXAMPLE)
    assert len(tl.entries) == 7
    assert isinstance(tl.entries[0].tag, CaTag)
    assert all(isinstance(e.tag, (CaTag, AfterPreviousTag)) for e in tl.entries)
    twin = tmp_path / "flyby-imaging.csv"
    twin.write_text(timeline_csv_text(tl), encoding="utf-8")
    assert load_timeline(twin) == tl


def test_load_refuses_unknown_format_and_missing_file(tmp_path: Path) -> None:
    """load_timeline names the file and the fault for an unknown suffix or an unreadable file."""
    with pytest.raises(TimelineError, match=r"unknown timeline format '\.txt'"):
        load_timeline(tmp_path / "t.txt")
    with pytest.raises(TimelineError, match=r"missing\.yaml: \(file\): cannot read"):
        load_timeline(tmp_path / "missing.yaml")


class _BurnArgs(Frozen):
    """Arguments of a test-only command."""

    delta_v_m_s: float = Field(gt=0, le=1.0, description="velocity change, m/s")


def test_registry_extends_without_touching_the_default() -> None:
    """A registered command parses in that registry only; a name registers once."""
    reg = default_registry()
    reg.register(CommandDefinition("trim_burn", _BurnArgs, "small trajectory trim"))
    text = "commands:\n  - {time: OBT 5, command: trim_burn, args: {delta_v_m_s: 0.2}}\n"
    assert timeline_from_yaml_text(text, registry=reg).entries[0].command == Command(
        name="trim_burn", args={"delta_v_m_s": 0.2}
    )
    with pytest.raises(TimelineError, match="unknown command 'trim_burn'"):
        timeline_from_yaml_text(text)
    with pytest.raises(ValueError, match="already registered"):
        reg.register(CommandDefinition("trim_burn", _BurnArgs, "again"))
    with pytest.raises(ValueError, match="command name must be"):
        CommandDefinition("9lives", _BurnArgs, "bad name")
    with pytest.raises(CommandError) as err:
        reg.command("trim_burn", {"delta_v_m_s": 2})
    assert err.value.problems == [("delta_v_m_s", "must be <= 1, got 2")]


def test_timeline_refuses_a_relative_first_entry() -> None:
    """A Timeline built in code cannot start with a tag relative to a previous command."""
    cmd = default_registry().command("stop_imaging")
    with pytest.raises(ValueError, match="row 1: a tag relative to the previous command"):
        Timeline(entries=(TimelineEntry(tag=AfterPreviousTag(delay_s=1.0), command=cmd),))


def test_utc_tag_is_normalised_to_utc() -> None:
    """A UTC tag given in another zone denotes the same instant, stored in UTC."""
    tz = timezone(timedelta(hours=-5))
    tag = UtcTag(utc=datetime(2022, 9, 26, 18, 10, 24, tzinfo=tz))
    assert tag.utc.tzinfo == UTC and tag.utc.hour == 23
