"""Run-folder tools read a damaged archive gracefully: a clear message, exit 2, tm.bin as fallback, no write."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from contracts import pus
from flyby.cli import main
from ground.archive import Archive

HK = pus.Housekeeping(mode=pus.Mode.STANDBY, q=(0.0, 0.0, 0.0, 1.0), rate_rad_s=(0.01, 0.02, 0.03),
                      wheel_speed_rad_s=(1.0, 2.0, 3.0), wheel_momentum_nms=(0.001, 0.002, 0.003))


def _run_folder(tmp_path: Path, n: int = 5) -> Path:
    """A run folder with an archive and tm.bin of ``n`` housekeeping packets, 1 s apart."""
    folder = tmp_path / "run"
    folder.mkdir()
    with Archive(folder / "archive.sqlite") as archive:
        for k in range(n):
            archive.store(pus.encode_tm(HK, 0x0C1, k, 1000.0 + k, k), 10.0 + k)
    for extra in folder.glob("archive.sqlite-*"):  # a cleanly closed WAL database leaves none
        extra.unlink()
    return folder


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.iterdir()}


DAMAGE = {
    "empty": lambda p: p.write_bytes(b""),
    "garbage": lambda p: p.write_bytes(os.urandom(4096)),
    "truncated": lambda p: p.write_bytes(p.read_bytes()[:1500]),
    "text": lambda p: p.write_text("not a database\n"),
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_flyby_tm_falls_back_on_tm_bin_and_exits_2(tmp_path: Path, damage: str, capsys) -> None:
    """A damaged archive: the values come from tm.bin, stderr says why, exit 2, the folder is left untouched."""
    folder = _run_folder(tmp_path)
    DAMAGE[damage](folder / "archive.sqlite")
    before = _snapshot(folder)
    code = main(["tm", str(folder), "--param", "Housekeeping.rate_rad_s[2]"])
    out, err = capsys.readouterr()
    assert code == 2
    assert "archive.sqlite" in err and "tm.bin" in err
    assert out.splitlines()[0] == "# Housekeeping.rate_rad_s[2]: 5 sample(s)"
    assert [float(line.split("\t")[0]) for line in out.splitlines()[2:]] == [1000.0 + k for k in range(5)]
    assert _snapshot(folder) == before


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_without_tm_bin_a_damaged_archive_is_a_clear_error(tmp_path: Path, damage: str, capsys) -> None:
    """Nothing to fall back on: one line naming the archive and what is wrong, exit 2, nothing printed."""
    folder = _run_folder(tmp_path)
    (folder / "tm.bin").unlink()
    DAMAGE[damage](folder / "archive.sqlite")
    before = _snapshot(folder)
    code = main(["tm", str(folder)])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("flyby tm: ") and "archive.sqlite" in err and "Traceback" not in err
    assert _snapshot(folder) == before


def test_flyby_ground_run_prints_from_tm_bin_without_receipt_times(tmp_path: Path, capsys) -> None:
    """``flyby ground --run`` on a damaged archive prints the housekeeping lines from tm.bin, UTC unknown, exit 2."""
    folder = _run_folder(tmp_path)
    DAMAGE["garbage"](folder / "archive.sqlite")
    code = main(["ground", "--run", str(folder)])
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert code == 2 and len(lines) == 5 and all(line.startswith("UTC         -   OBT") for line in lines)


def test_an_intact_archive_is_read_without_writing(tmp_path: Path, capsys) -> None:
    """Reading an intact archive creates no journal or shared-memory file in the run folder."""
    folder = _run_folder(tmp_path)
    before = _snapshot(folder)
    assert main(["tm", str(folder)]) == 0
    assert main(["ground", "--run", str(folder)]) == 0
    assert _snapshot(folder) == before


def test_flyby_report_writes_from_tm_bin_and_exits_2(tmp_path: Path, capsys) -> None:
    """``flyby report`` on a damaged archive still writes the report (telemetry from tm.bin), says why, exits 2."""
    folder = _run_folder(tmp_path)
    (folder / "scenario.yaml").write_text("name: damaged\n")
    DAMAGE["truncated"](folder / "archive.sqlite")
    code = main(["report", str(folder)])
    _, err = capsys.readouterr()
    assert code == 2 and "archive.sqlite" in err
    page = (folder / "report.html").read_text()
    assert "archive.sqlite unusable" in page
