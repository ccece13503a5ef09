"""The camera frames of a step record that keeps them by reference, rendered again for ``flyby replay``.

The universe is deterministic: a frame follows from the true time, attitude and body rate at its exposure, the
scenario (bodies, faults, camera) and the camera's noise streams, drawn frame after frame. A new universe of the
recorded scenario, asked for each recorded frame in order with the truth at its exposure (the record's own, written
by a run in one process, or the ``truth.csv`` beside the record, written by ground in a run over the bus), renders
the run's frames again. Each is checked against the recorded digest: one that differs stops the replay, since the
flight software would be fed frames it never saw.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from analysis.truth import read_truth_records
from contracts.errors import FlybyError, ScenarioError
from contracts.steplog import FrameTruth, RecordedStep, frame_digest
from contracts.truthtable import TruthTableError
from scenario import compose
from scenario.model import Scenario, scenario_from_dict
from universe.simulator import Universe

TRUTH_TABLE = "truth.csv"
"""The truth table of a run folder, beside the record."""


class FrameMismatch(FlybyError):
    """A frame rendered again differs from the recorded one: the universe or the scenario changed since the run."""


class RecordedFramesError(FlybyError):
    """The frames of a record cannot be rendered again: no scenario, no truth for a frame, or a frame missing."""


class RecordedFrames:
    """Renders, in order, the frames a record keeps by reference.

    ``scenario``: the scenario to render them from (default: the one recorded in ``header``); ``record``: the
    record's path, whose folder holds the run's ``truth.csv`` for frames recorded without their truth.
    """

    def __init__(self, record: Path, header: dict[str, Any], scenario: Scenario | None = None) -> None:
        self.record = Path(record)
        self._header = header
        self._scenario = scenario
        self._universe: Universe | None = None
        self._table: dict[int, FrameTruth] | None = None
        self._next_id = 0

    def with_pixels(self, steps: Iterable[RecordedStep],
                    ahead: int = 4) -> Iterator[tuple[RecordedStep, np.ndarray | None]]:
        """Each of ``steps`` with its frame's pixels (read from the record, rendered again, or None), rendering up to
        ``ahead`` frames before they are asked for, in a thread of its own: the camera kernels release the
        interpreter lock, so rendering overlaps the caller's work (the flight software's steps)."""
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="render")  # one worker: frames in order
        window: deque[tuple[RecordedStep, Future[np.ndarray] | None]] = deque()
        pending = 0
        try:
            for st in steps:
                job = None if st.frame_digest is None else pool.submit(self.pixels, st)
                window.append((st, job))
                pending += job is not None
                while pending >= ahead:
                    first, done = window.popleft()
                    pending -= done is not None
                    yield first, first.frame if done is None else done.result()
            for first, done in window:
                yield first, first.frame if done is None else done.result()
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def pixels(self, st: RecordedStep) -> np.ndarray:
        """The frame of ``st`` (one kept by reference) rendered again; FrameMismatch if its digest is not the
        recorded one, RecordedFramesError if it cannot be rendered."""
        meta = st.request.frame
        assert meta is not None and st.frame_digest is not None, "a step without a frame kept by reference"
        where = f"frame {meta.frame_id} (step {st.request.step}, OBT {meta.obt_s:.3f} s)"
        if meta.frame_id != self._next_id:
            # the noise of a frame depends on every frame before it: none may be missing
            raise RecordedFramesError(f"{self.record}: {where} is not frame {self._next_id}, the next one the run "
                                      "rendered: a record with frames missing cannot be rendered again")
        truth = st.frame_truth if st.frame_truth is not None else self._truth_table(where).get(meta.frame_id)
        if truth is None:
            raise RecordedFramesError(f"{self.record.parent / TRUTH_TABLE}: no row for {where}, which the record "
                                      "keeps by reference: it cannot be rendered again")
        pixels = self._build().frame_at(truth.t_s, truth.q, truth.omega_rad_s, meta.exposure_s)
        self._next_id += 1
        blob = pixels.astype("<u2", copy=False).tobytes()
        digest = frame_digest(blob)
        if digest != st.frame_digest:
            raise FrameMismatch(
                f"{where}: rendered again from the scenario and the truth at its exposure, its pixels hash to "
                f"{digest.hex()}, the record's to {st.frame_digest.hex()} (BLAKE2b-64): the universe or the scenario "
                f"changed since the run, so the flight software would be fed a frame it never saw; replay with the "
                "build of the run, or record with --record-frames raw to replay across universe changes")
        return np.frombuffer(blob, dtype="<u2").reshape(meta.height, meta.width)

    def _build(self) -> Universe:
        """The universe of the scenario, made on the first frame (its shape models take a moment)."""
        if self._universe is None:
            if self._scenario is None:
                recorded = self._header.get("scenario")
                if not isinstance(recorded, dict):
                    raise RecordedFramesError(f"{self.record}: the record keeps frames by reference but holds no "
                                              "scenario to render them from")
                try:
                    self._scenario = scenario_from_dict(recorded, f"{self.record}: recorded scenario")
                except ScenarioError as err:
                    raise RecordedFramesError(f"{err.source} no longer loads: {'; '.join(err.problems)}") from None
            self._universe = compose.universe(self._scenario)
        return self._universe

    def _truth_table(self, where: str) -> dict[int, FrameTruth]:
        """The truth at each frame's exposure from ``truth.csv`` beside the record, by frame id."""
        if self._table is None:
            path = self.record.parent / TRUTH_TABLE
            if not path.is_file():
                raise RecordedFramesError(f"{self.record}: {where} is kept by reference without its truth, and there "
                                          f"is no {path} to render it from")
            try:
                records = read_truth_records(path)[0]
            except TruthTableError as err:
                raise RecordedFramesError(str(err)) from None
            self._table = {r.frame_id: FrameTruth(t_s=r.t_s, q=r.q, omega_rad_s=r.omega_rad_s)
                           for r in records if r.frame_id is not None}
        return self._table
