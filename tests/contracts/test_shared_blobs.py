"""Blobs handed through the host's shared memory: the bytes read are the bytes written, references name only the
run's own files, and nothing stays behind."""

from __future__ import annotations

import itertools
import os
import shutil
import sys
from collections.abc import Iterator

import numpy as np
import pytest

from contracts import shared_blobs
from contracts.shared_blobs import BlobSharer, SharedBlobError, is_reference, open_blob, run_folder

pytestmark = pytest.mark.skipif(not (sys.platform.startswith("linux") and shared_blobs.shared_memory_available()),
                                reason="needs a writable /dev/shm")

_RUNS = itertools.count()


@pytest.fixture
def run_id() -> Iterator[str]:
    """A run id of this test's own, its shared-memory folder removed afterwards."""
    rid = f"test-{os.getpid()}-{next(_RUNS)}"
    yield rid
    shutil.rmtree(run_folder(rid), ignore_errors=True)


def test_a_shared_frame_reads_back_identical(run_id: str) -> None:
    """A 16-bit frame shared and opened again is the same array, octet for octet."""
    frame = np.random.default_rng(1).integers(0, 4096, size=(1024, 1024), dtype=np.uint16)
    sharer = BlobSharer(run_id)
    ref = sharer.share(frame.tobytes())
    assert is_reference(ref) and len(ref) < 64  # the message carries a name, not the pixels
    got = np.frombuffer(open_blob(run_id, ref), dtype=np.uint16).reshape(frame.shape)
    assert np.array_equal(got, frame)
    sharer.close()


def test_a_released_blob_stays_readable_where_it_is_mapped_and_its_file_is_gone(run_id: str) -> None:
    """Release removes the file; a mapping the peer already holds still reads the blob; close removes the folder."""
    sharer = BlobSharer(run_id)
    ref = sharer.share(b"\x01\x02" * 40_000)
    view = open_blob(run_id, ref)
    sharer.release(ref)
    assert os.listdir(run_folder(run_id)) == []
    assert bytes(view) == b"\x01\x02" * 40_000
    with pytest.raises(SharedBlobError, match="blob-0"):
        open_blob(run_id, ref)
    sharer.close()
    assert not run_folder(run_id).exists()


@pytest.mark.parametrize("ref", [b"flyby-shm:../../etc/passwd:10", b"flyby-shm:blob-0", b"flyby-shm:blob-x:4",
                                 b"flyby-shm:blob-0:-1", b"flyby-shm:\xff:1"])
def test_a_reference_naming_no_blob_of_the_run_is_refused(run_id: str, ref: bytes) -> None:
    """A reference that is not blob-N:length names the reference in the error and opens nothing."""
    BlobSharer(run_id)
    with pytest.raises(SharedBlobError, match="reference"):
        open_blob(run_id, ref)


def test_a_length_other_than_the_file_is_refused(run_id: str) -> None:
    """A reference whose length disagrees with the file's is refused with both lengths."""
    sharer = BlobSharer(run_id)
    ref = sharer.share(b"\x00" * 100_000)
    with pytest.raises(SharedBlobError, match="holds 100000 octets, the reference says 99999"):
        open_blob(run_id, ref.replace(b":100000", b":99999"))


def test_a_folder_open_to_others_is_refused(run_id: str) -> None:
    """A run folder other users could write into (made before the sharer, say) is refused on both sides."""
    folder = run_folder(run_id)
    folder.mkdir()
    folder.chmod(0o777)
    with pytest.raises(SharedBlobError, match="closed to others"):
        BlobSharer(run_id)
    with pytest.raises(SharedBlobError, match="closed to others"):
        open_blob(run_id, b"flyby-shm:blob-0:1")
