"""Every compiled kernel of the universe, warmed up at once: what the node calls before its first period (and the
test session in the background), so that no compilation lands inside the control loop."""

from __future__ import annotations

from universe import attitude_rk4, geometry_kernels, sensor_kernels
from universe.camera import warm_up as camera_warm_up


def warm_up(camera: bool = True) -> None:
    """Compile, or load from the cache, every kernel of the universe: the camera's (unless ``camera`` is False: runs
    at centroid level render nothing), the dynamics', the sensors' and the truth geometry's (seconds on the first run
    after an install)."""
    if camera:
        camera_warm_up()
    attitude_rk4.warm_up()
    sensor_kernels.warm_up()
    geometry_kernels.warm_up()
