"""The results of a campaign: one SQLite file, one row per run appended as the run finishes.

SQLite rather than Parquet: a row is appended and committed in its own transaction, so a campaign killed at any
moment keeps every run stored before it (the journal rolls a half-written row back), and ``--resume`` asks the
file which runs it holds. A Parquet file is written whole: appending run by run would mean a file per run or a
rewrite per run. SQLite is in Python's standard library and any tool reads it.

Tables: ``campaign`` (key, value: the campaign's JSON, how it was started), ``runs`` (one row per run: identity,
outcome, timing, the figures of ``flyby.montecarlo.figures`` and the verdicts) and ``dispersed`` (run, path, value:
the values drawn for each run, one row per column of ``scenario.dispersions.draw``).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flyby.montecarlo.figures import EVENT_NAMES, FIGURES, LIMITS, REQUIREMENTS

if TYPE_CHECKING:
    from flyby.montecarlo.campaign import RunResult

STORE_NAME = "results.sqlite"
IDENTITY = (("run", "INTEGER PRIMARY KEY"), ("seed", "INTEGER NOT NULL"), ("status", "TEXT NOT NULL"),
            ("error", "TEXT"), ("wall_s", "REAL"), ("sim_s", "REAL"))
FIGURE_COLUMNS: tuple[tuple[str, str], ...] = (
    *((f.name, "REAL") for f in FIGURES), *((name, "REAL") for name in LIMITS),
    *((f"{req}_pass", "INTEGER") for req, _ in REQUIREMENTS), ("all_pass", "INTEGER"), ("modes", "TEXT"),
    *((f"events_{n}", "INTEGER") for n in EVENT_NAMES))
COLUMNS = IDENTITY + FIGURE_COLUMNS


class StoreError(Exception):
    """The results file cannot be used for this campaign (another campaign's, or not a results file)."""


class ResultStore:
    """A campaign's results file: its definition, and the rows of the runs done."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.con = sqlite3.connect(self.path)
        self.con.execute("PRAGMA synchronous = FULL")  # a committed row survives a power cut, not only a kill
        with self.con:
            self.con.execute("CREATE TABLE IF NOT EXISTS campaign (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
            cols = ", ".join(f'"{name}" {kind}' for name, kind in COLUMNS)
            self.con.execute(f"CREATE TABLE IF NOT EXISTS runs ({cols})")
            self.con.execute("CREATE TABLE IF NOT EXISTS dispersed (run INTEGER NOT NULL, path TEXT NOT NULL, "
                             "value REAL, PRIMARY KEY (run, path))")
        have = [r[1] for r in self.con.execute("PRAGMA table_info(runs)")]
        if have != [name for name, _ in COLUMNS]:
            raise StoreError(f"{self.path}: its runs table has other columns than this version writes; "
                             "start a new campaign folder")

    def close(self) -> None:
        """Close the file."""
        self.con.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def meta(self) -> dict[str, str]:
        """The campaign's key/value definition (empty for a new file)."""
        return dict(self.con.execute("SELECT key, value FROM campaign"))

    def set_meta(self, values: dict[str, str]) -> None:
        """Store (or replace) definition entries."""
        with self.con:
            self.con.executemany("INSERT OR REPLACE INTO campaign (key, value) VALUES (?, ?)", values.items())

    def append(self, r: RunResult) -> None:
        """Store one run and its drawn values in one transaction."""
        row: dict[str, Any] = {"run": r.run, "seed": r.seed, "status": r.status, "error": r.error, "wall_s": r.wall_s,
                               "sim_s": r.sim_s, **r.figures}
        names = [name for name, _ in COLUMNS if name in row]
        quoted = ", ".join('"' + n + '"' for n in names)
        with self.con:
            self.con.execute(f"INSERT INTO runs ({quoted}) VALUES ({', '.join('?' for _ in names)})",
                             [row[n] for n in names])
            self.con.executemany("INSERT INTO dispersed (run, path, value) VALUES (?, ?, ?)",
                                 [(r.run, p, v) for p, v in r.values.items()])

    def done(self) -> set[int]:
        """The runs stored."""
        return {k for (k,) in self.con.execute("SELECT run FROM runs")}

    def rows(self) -> list[dict[str, Any]]:
        """Every stored run as a mapping of its columns, by run."""
        cur = self.con.execute("SELECT * FROM runs ORDER BY run")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r)) for r in cur]

    def values(self) -> dict[int, dict[str, float]]:
        """run -> {dispersed column: drawn value}."""
        out: dict[int, dict[str, float]] = {}
        for run, path, value in self.con.execute("SELECT run, path, value FROM dispersed ORDER BY run, path"):
            out.setdefault(run, {})[path] = value
        return out


@contextmanager
def open_store(folder: Path) -> Iterator[ResultStore]:
    """The results file of a campaign folder (created if absent)."""
    folder.mkdir(parents=True, exist_ok=True)
    store = ResultStore(folder / STORE_NAME)
    try:
        yield store
    finally:
        store.close()
