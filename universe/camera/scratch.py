"""Per-thread float32 work buffers of the renderer: fresh multi-MB arrays would cost page faults every frame."""

from __future__ import annotations

import threading

import numpy as np

_SCRATCH = threading.local()


def work_buffer(name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A reusable float32 work array of ``shape`` (contents undefined), private to this thread and ``name``."""
    n = int(np.prod(shape))
    buf = getattr(_SCRATCH, name, None)
    if buf is None or buf.size < n:
        buf = np.empty(max(n, 1), dtype=np.float32)
        setattr(_SCRATCH, name, buf)
    return buf[:n].reshape(shape)
