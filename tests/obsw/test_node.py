"""The OBSW node's frame intake: pixels from the blob, or none at all at centroid-level fidelity."""

from __future__ import annotations

import numpy as np
import pytest

from contracts.messages import CentroidMeasurement, FrameMeta, SensorData, StepRequest
from obsw.node import frame_pixels

MEASUREMENT = CentroidMeasurement(dimorphos_col_row=(10.0, 20.0), dimorphos_area_px=4.0, didymos_col_row=None,
                                  didymos_area_px=0.0)


def _request(measurement: CentroidMeasurement | None) -> StepRequest:
    meta = FrameMeta(frame_id=3, obt_s=1.0, width=4, height=2, bit_depth=12, exposure_s=0.01, measurement=measurement)
    return StepRequest(step=1, obt_s=1.0, frame=meta,
                       sensors=SensorData(star_tracker_q=None, gyro_rad_s=(0.0, 0.0, 0.0), wheel_speed_rad_s=()))


def test_pixels_come_from_the_blob() -> None:
    """A frame's blob is its little-endian uint16 pixels, row-major."""
    px = np.arange(8, dtype="<u2").reshape(2, 4)
    np.testing.assert_array_equal(frame_pixels(_request(None), px.tobytes()), px)


def test_a_measurement_carries_no_pixels() -> None:
    """A frame with a measurement gives no pixels; one that also carries pixel bytes is refused, naming the frame."""
    assert frame_pixels(_request(MEASUREMENT), b"") is None
    with pytest.raises(ValueError, match="frame 3 carries a measurement"):
        frame_pixels(_request(MEASUREMENT), b"\0" * 16)
