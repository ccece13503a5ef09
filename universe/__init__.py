"""Universe simulator: the truth (geometry, dynamics, sensors, camera, faults, link, on-board oscillator)."""
