"""``flyby tm``: parameter listing, printing and CSV export of a run's archive read back to the stored values."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from contracts import pus
from flyby.cli import main
from ground.archive import Archive
from ground.tmquery import TmQueryError, export_parameters_csv, parameter_counts, parameter_samples

APID = 0x0C1
OBT0 = 26_499_000.0


def rate_x(i: int) -> float:
    """A value that float32 cannot hold exactly, so the test sees the archive's f32 rounding."""
    return 0.001 * i + 1e-9 * i * i


def make_archive(run: Path, n: int = 30) -> list[float]:
    """Housekeeping packets at OBT0 + i s; every third carries a pointing error; return the OBT stamps."""
    run.mkdir(parents=True, exist_ok=True)
    obts = []
    with Archive(run / "archive.sqlite", tm_bin=run / "tm.bin") as archive:
        for i in range(n):
            hk = pus.Housekeeping(
                mode=pus.Mode(i % 5), q=(0.0, 0.0, 0.0, 1.0), rate_rad_s=(rate_x(i), 0.0, -1.0),
                wheel_speed_rad_s=(1.0, 2.0, 3.0), wheel_momentum_nms=(0.0, 0.0, 0.0),
                pointing_error_rad=0.01 * i if i % 3 == 0 else None)
            obt = OBT0 + i + 0.25
            archive.store(pus.encode_tm(hk, APID, i, obt, i), 100.0 + i)
            obts.append(obt)
        archive.store(pus.encode_tm(pus.TimeReport(obt_s=OBT0), APID, n, OBT0, n), 200.0)
    return obts


def read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a CSV file."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_csv_export_reads_back_the_stored_values(tmp_path: Path) -> None:
    """`flyby tm --csv` writes one row per packet whose cells parse back to the float32 values sent."""
    run = tmp_path / "run"
    obts = make_archive(run)
    out = tmp_path / "rate.csv"
    assert main(["tm", str(run), "--param", "Housekeeping.rate_rad_s[0]", "--param", "Housekeeping.mode",
                 "--csv", str(out)]) == 0
    header, rows = read_csv(out)
    assert header[-2:] == ["Housekeeping.rate_rad_s[0]", "Housekeeping.mode"]
    assert [float(r[2]) for r in rows] == pytest.approx(obts, abs=2e-5)  # CUC 2^-16 s time stamps
    assert [float(r[-2]) for r in rows] == [float(np.float32(rate_x(i))) for i in range(len(obts))]
    assert [int(r[-1]) for r in rows] == [i % 5 for i in range(len(obts))]


def test_csv_export_obeys_the_obt_range(tmp_path: Path) -> None:
    """--from/--to keep exactly the packets with OBT in the closed range."""
    run = tmp_path / "run"
    obts = make_archive(run)
    out = tmp_path / "pe.csv"
    lo, hi = obts[5], obts[20]
    n = export_parameters_csv(run, ["Housekeeping.pointing_error_rad"], out, lo - 0.1, hi + 0.1)
    _, rows = read_csv(out)
    expected = [i for i in range(5, 21) if i % 3 == 0]
    assert n == len(rows) == len(expected)
    assert [float(r[-1]) for r in rows] == [float(np.float32(0.01 * i)) for i in expected]


def test_listing_prints_every_parameter_with_its_count(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Without --param the command lists each archived parameter and how many samples it has."""
    run = tmp_path / "run"
    make_archive(run, n=30)
    assert main(["tm", str(run)]) == 0
    listed = dict(line.split("\t") for line in capsys.readouterr().out.splitlines())
    assert listed["Housekeeping.mode"] == "30"
    assert listed["Housekeeping.pointing_error_rad"] == "10"
    assert listed["TimeReport.obt_s"] == "1"
    assert dict(parameter_counts(run)) == {k: int(v) for k, v in listed.items()}


def test_printing_matches_the_archive_query(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Printed samples are the archive's samples in the range, values as stored."""
    run = tmp_path / "run"
    obts = make_archive(run)
    assert main(["tm", str(run), "--param", "Housekeeping.rate_rad_s[0]", "--from", str(obts[10]),
                 "--to", str(obts[12])]) == 0
    lines = capsys.readouterr().out.splitlines()
    values = [float(line.split("\t")[1]) for line in lines[2:]]
    assert values == [float(np.float32(rate_x(i))) for i in (10, 11, 12)]
    assert values == [s.value for s in parameter_samples(run, "Housekeeping.rate_rad_s[0]", obts[10], obts[12])]


def test_bad_requests_exit_2_and_create_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Unknown parameter, reversed range, or a folder without archive: exit 2 with a message, no file made."""
    run = tmp_path / "run"
    make_archive(run)
    assert main(["tm", str(run), "--param", "Housekeeping.nope"]) == 2
    assert "Housekeeping.nope" in capsys.readouterr().err
    assert main(["tm", str(run), "--param", "Housekeeping.mode", "--from", "5", "--to", "1"]) == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["tm", str(empty)]) == 2
    assert "no archive.sqlite" in capsys.readouterr().err
    assert list(empty.iterdir()) == []
    with pytest.raises(TmQueryError):
        parameter_samples(empty, "Housekeeping.mode")


def test_archive_without_tm_bin_is_read_without_creating_one(tmp_path: Path) -> None:
    """A run folder that lost tm.bin is still queried, and no tm.bin appears in it."""
    run = tmp_path / "run"
    make_archive(run)
    (run / "tm.bin").unlink()
    assert len(parameter_samples(run, "Housekeeping.mode")) == 30
    assert not (run / "tm.bin").exists()
