"""Scene inputs are checked on creation, with errors naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from tests.universe.camera.common import scene
from universe.camera import Body, RenderError


def test_bad_inputs_raise_named_errors() -> None:
    """Invalid scene fields raise RenderError naming the field."""
    with pytest.raises(RenderError, match="exposure_s"):
        scene(exposure_s=0.0)
    with pytest.raises(RenderError, match="sun_direction"):
        scene(sun=(0.0, 0.0, 0.0))
    with pytest.raises(RenderError, match="plume_body_index"):
        scene(plume_body_index=0)
    with pytest.raises(RenderError, match="radius_m"):
        Body(np.zeros(3), -1.0)
