"""``flyby tm``: the telemetry archive of a run folder, queried by parameter and OBT range, printed or as CSV.

Parameters are named as the archive stores them, ``<Report>.<field>`` with ``[i]`` for items
(``Housekeeping.rate_rad_s[2]``); without ``--param`` the command lists every name with its sample count.
"""

from __future__ import annotations

import argparse
import csv
import math
import sqlite3
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from contracts.errors import FlybyError
from contracts.exitcodes import EXIT_CONFIG as EXIT_USAGE
from contracts.pus import complete_packets
from ground.archive import Archive, ArchiveError, Sample



class TmQueryError(FlybyError):
    """A ``flyby tm`` request that cannot be answered: no archive in the folder, unknown parameter, bad range."""


@contextmanager
def run_archive(run_dir: Path) -> Iterator[Archive]:
    """The archive of a run folder, opened for reading only (nothing is written into the folder).

    If archive.sqlite is missing or damaged but the raw tm.bin is there, the archive is rebuilt in memory from
    tm.bin (receipt times are unknown there and read 0) and ``archive.damage`` says why; TmQueryError if neither
    can serve.
    """
    db, tm_bin = Path(run_dir) / "archive.sqlite", Path(run_dir) / "tm.bin"
    if not Path(run_dir).is_dir():
        raise TmQueryError(f"{run_dir}: no such folder")
    if not db.is_file() and not tm_bin.is_file():
        raise TmQueryError(f"{run_dir}: no archive.sqlite and no tm.bin (is this a run folder?)")
    try:
        archive = Archive.read_only(db)
    except ArchiveError as exc:
        if not tm_bin.is_file():
            raise TmQueryError(f"{exc}; and no tm.bin to fall back on (is this a run folder?)") from None
        with tempfile.TemporaryDirectory() as tmp:
            with Archive(":memory:", tm_bin=Path(tmp) / "tm.bin") as rebuilt:
                packets, tail = complete_packets(tm_bin.read_bytes())
                rebuilt.store_many(packets, 0.0)
                rebuilt.damage = (f"{exc}: read {len(packets)} packet(s) from tm.bin instead (receipt times unknown)"
                                  + (f", ignoring {tail} octets of an incomplete last packet" if tail else ""))
                yield rebuilt
        return
    try:
        yield archive
    except sqlite3.DatabaseError as exc:  # damage deeper in the file, met by a query
        raise TmQueryError(f"{db}: damaged database: {exc}") from None
    finally:
        archive.close()


def parameter_counts(run_dir: Path) -> list[tuple[str, int]]:
    """Every parameter name of the run's archive, sorted, with its number of samples."""
    with run_archive(run_dir) as archive:
        return [(name, len(archive.query(name))) for name in archive.parameter_names()]


def _check_range(obt_from: float, obt_to: float) -> None:
    if math.isnan(obt_from) or math.isnan(obt_to) or obt_from > obt_to:
        raise TmQueryError(f"--from {obt_from} must not be after --to {obt_to} (OBT s)")


def _check_known(archive: Archive, names: Sequence[str]) -> None:
    known = set(archive.parameter_names())
    unknown = [n for n in names if n not in known]
    if unknown:
        raise TmQueryError(f"no such parameter(s) in {archive.path}: {', '.join(unknown)} "
                           "(run 'flyby tm RUN_DIR' without --param to list them)")


def parameter_samples(run_dir: Path, name: str, obt_from: float = -math.inf,
                      obt_to: float = math.inf) -> list[Sample]:
    """Every sample of ``name`` with obt_from <= OBT <= obt_to, in OBT order."""
    _check_range(obt_from, obt_to)
    with run_archive(run_dir) as archive:
        _check_known(archive, [name])
        return archive.query(name, obt_from, obt_to)


def export_parameters_csv(run_dir: Path, names: Sequence[str], out: Path, obt_from: float = -math.inf,
                          obt_to: float = math.inf) -> int:
    """Write the packets carrying any of ``names`` with OBT in [obt_from, obt_to] as CSV (Archive.export_csv
    columns: packet_id, receipt_utc_s, obt_s, apid, seq_count, one column per parameter); return the row count."""
    _check_range(obt_from, obt_to)
    with run_archive(run_dir) as archive:
        _check_known(archive, names)
        if math.isinf(obt_from) and math.isinf(obt_to):
            return archive.export_csv(names, out)
        with tempfile.TemporaryDirectory() as tmp:
            full = Path(tmp) / "all.csv"
            archive.export_csv(names, full)
            with open(full, newline="") as src, open(out, "w", newline="") as dst:
                reader, writer = csv.reader(src), csv.writer(dst)
                header = next(reader)
                at = header.index("obt_s")
                writer.writerow(header)
                rows = [r for r in reader if obt_from <= float(r[at]) <= obt_to]
                writer.writerows(rows)
            return len(rows)


def cmd_tm(args: argparse.Namespace) -> int:
    """``flyby tm RUN_DIR [--param NAME ...] [--from OBT] [--to OBT] [--csv OUT]``; exit 2 on a bad request."""
    obt_from = -math.inf if args.obt_from is None else args.obt_from
    obt_to = math.inf if args.obt_to is None else args.obt_to
    try:
        with run_archive(args.run_dir) as archive:
            damage = archive.damage
        if damage:  # served from tm.bin all the same; exit 2 afterwards so a script sees the damage
            print(f"flyby tm: {damage}", file=sys.stderr)
        if not args.param:
            if args.csv is not None:
                raise TmQueryError("--csv needs at least one --param")
            for name, n in parameter_counts(args.run_dir):
                print(f"{name}\t{n}")
            return EXIT_USAGE if damage else 0
        if args.csv is not None:
            n = export_parameters_csv(args.run_dir, args.param, args.csv, obt_from, obt_to)
            print(f"{n} packet(s) written to {args.csv}", file=sys.stderr)
            return EXIT_USAGE if damage else 0
        for name in args.param:
            samples = parameter_samples(args.run_dir, name, obt_from, obt_to)
            print(f"# {name}: {len(samples)} sample(s)\nobt_s\tvalue")
            for s in samples:
                print(f"{s.obt_s!r}\t{s.value!r}")
        return EXIT_USAGE if damage else 0
    except (TmQueryError, ArchiveError) as err:
        print(f"flyby tm: {err}", file=sys.stderr)
        return EXIT_USAGE


def add_tm_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``flyby tm``."""
    p.add_argument("run_dir", type=Path)
    p.add_argument("--param", action="append", default=[], metavar="NAME",
                   help="parameter to print or export (repeatable); without it, list the parameters")
    p.add_argument("--from", dest="obt_from", type=float, default=None, metavar="OBT", help="first OBT, s")
    p.add_argument("--to", dest="obt_to", type=float, default=None, metavar="OBT", help="last OBT, s")
    p.add_argument("--csv", type=Path, default=None, metavar="OUT", help="write a CSV file instead of printing")
    p.set_defaults(func=cmd_tm)
