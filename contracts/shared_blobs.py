"""Blobs (camera frames) handed to a peer on the same host through shared memory instead of through the link.

A message's blob is written once into a file of its own in the run's folder of the host's shared memory
(``/dev/shm/flyby-<run id>/``, a tmpfs: memory, never the disk); the message travels without it, carrying in its
Zenoh attachment a reference (the file's name and length). The receiver maps that file read-only and hands the
mapping on as the blob: its pixels are read where the sender wrote them, with no copy through TLS, the socket and
the decoder (a 2 MB frame was copied six times on that path). The sender removes the file once the peer has
answered the message (a peer answers only after it has taken the blob); the peer's mapping lives on until its last
user drops it. Only nodes on one host can do this: ``flyby run`` turns it on, nodes started by hand on separate
hosts keep the blob in the message.

The folder is private to the user (mode 0700) and the receiver opens only names this module makes, without
following links, so a reference cannot point a node at any other file.
"""

from __future__ import annotations

import mmap
import os
import re
import shutil
import stat
from pathlib import Path

SHM_ROOT = Path("/dev/shm")
_PREFIX = b"flyby-shm:"
_NAME = re.compile(r"blob-[0-9]{1,12}")
MIN_SHARED_OCTETS = 64 * 1024  # smaller blobs stay in the message: a file costs more than copying them


class SharedBlobError(Exception):
    """A shared blob could not be written or read (its reference, file or length is wrong)."""


def shared_memory_available() -> bool:
    """Whether this host has a writable shared-memory file system at ``SHM_ROOT``."""
    return SHM_ROOT.is_dir() and os.access(SHM_ROOT, os.W_OK | os.X_OK)


def run_folder(run_id: str) -> Path:
    """The shared-memory folder of a run's blobs."""
    return SHM_ROOT / f"flyby-{run_id}"


class BlobSharer:
    """The sending side: writes blobs into the run's shared-memory folder and removes them when released."""

    def __init__(self, run_id: str) -> None:
        self.folder = run_folder(run_id)
        try:
            self.folder.mkdir(mode=0o700, exist_ok=True)
        except OSError as exc:
            raise SharedBlobError(f"shared memory {self.folder}: {exc}") from None
        check_folder(self.folder)
        self._next = 0
        self._live: set[str] = set()

    def share(self, blob: bytes | memoryview) -> bytes:
        """Write ``blob`` into a new file and return its reference (for the message's attachment)."""
        name = f"blob-{self._next}"
        self._next += 1
        path = self.folder / name
        view = memoryview(blob).cast("B")
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
            try:
                done = 0
                while done < view.nbytes:
                    done += os.write(fd, view[done:])
            finally:
                os.close(fd)
        except OSError as exc:
            raise SharedBlobError(f"shared memory {path}: {exc}") from None
        self._live.add(name)
        return _PREFIX + f"{name}:{view.nbytes}".encode()

    def release(self, reference: bytes) -> None:
        """Remove the file of ``reference`` (the peer keeps its mapping, if it has one)."""
        name = reference[len(_PREFIX):].split(b":", 1)[0].decode()
        if name in self._live:
            self._live.discard(name)
            try:
                (self.folder / name).unlink()
            except FileNotFoundError:
                pass

    def close(self) -> None:
        """Remove every file still shared, and the folder."""
        self._live.clear()
        shutil.rmtree(self.folder, ignore_errors=True)


def check_folder(folder: Path) -> None:
    """Refuse a run folder that is not a real folder of this user's, closed to others (one another user made first,
    or a link, could hand a node frames that are not the universe's)."""
    try:
        st = os.lstat(folder)
    except OSError as exc:
        raise SharedBlobError(f"shared memory {folder}: {exc.strerror}") from None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        raise SharedBlobError(f"shared memory {folder} is not a folder of this user's closed to others "
                              f"(mode {stat.filemode(st.st_mode)}, owner uid {st.st_uid})")


def is_reference(attachment: bytes | None) -> bool:
    """Whether a message's attachment refers to a shared blob."""
    return attachment is not None and attachment.startswith(_PREFIX)


def open_blob(run_id: str, reference: bytes) -> memoryview:
    """The blob of ``reference``, mapped read-only from the run's shared-memory folder (no copy)."""
    try:
        name, length = reference[len(_PREFIX):].decode("ascii").split(":")
        size = int(length)
    except ValueError:
        raise SharedBlobError(f"shared blob reference {reference[:64]!r} is not name:length") from None
    if not _NAME.fullmatch(name) or size < 0:
        raise SharedBlobError(f"shared blob reference {reference[:64]!r} names no blob of this run")
    check_folder(run_folder(run_id))
    path = run_folder(run_id) / name
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as exc:
        raise SharedBlobError(f"shared blob {path}: {exc.strerror} (the nodes must share a host to pass frames "
                              "through shared memory)") from None
    try:
        actual = os.fstat(fd).st_size
        if actual != size:
            raise SharedBlobError(f"shared blob {path} holds {actual} octets, the reference says {size}")
        if size == 0:
            return memoryview(b"")
        return memoryview(mmap.mmap(fd, size, prot=mmap.PROT_READ))
    finally:
        os.close(fd)
