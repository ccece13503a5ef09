"""The timing model: execution times linear in the work reported, a frame's delay from its exposure in closed form."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from contracts.task import Task
from obsw.timing import TimingConfig, TimingModel, Work

counts = st.integers(0, 100_000)


def test_the_default_frame_delay_is_exposure_readout_and_fpga_passes() -> None:
    """A 1024 x 1024 12-bit frame of 10 ms: 5 ms of exposure left, 12,582,912 bit at 80 Mbit/s (157.3 ms), then
    262,144 binned pixels at 20 ns (binarisation) and 40 ns (labelling): 178.0 ms."""
    delay = TimingModel(TimingConfig()).frame_delay_s(1024, 1024, 12, 0.01, 512 * 512)
    assert delay == pytest.approx(0.005 + 0.1572864 + 0.00524288 + 0.01048576, abs=1e-12)


@given(w=st.sampled_from([1024, 2048]), bits=st.integers(8, 16), rate=st.floats(1e6, 1e9),
       exposure=st.floats(1e-4, 0.5), binned=st.integers(1, 2048 * 2048),
       per_px=st.tuples(st.floats(0, 1e-7), st.floats(0, 1e-7), st.floats(0, 1e-7)))
def test_frame_delay_is_linear_in_bits_and_binned_pixels(w, bits, rate, exposure, binned, per_px) -> None:
    """Delay = exposure / 2 + w h bits / rate + binned pixels x the three FPGA stages; none when not modelled."""
    cfg = TimingConfig(camera_link_rate_bps=rate, fpga_filtering_s_per_binned_pixel=per_px[0],
                       fpga_binarisation_s_per_binned_pixel=per_px[1], fpga_labelling_s_per_binned_pixel=per_px[2])
    expected = exposure / 2 + w * w * bits / rate + binned * sum(per_px)
    assert TimingModel(cfg).frame_delay_s(w, w, bits, exposure, binned) == pytest.approx(expected, rel=1e-12)
    off = cfg.model_copy(update={"modelled": False})
    assert TimingModel(off).frame_delay_s(w, w, bits, exposure, binned) == 0.0


@given(commands=counts, regions=counts, pixels=counts, frames=counts, candidates=counts, measurements=counts,
       checks=counts, packets=counts, samples=counts)
def test_execution_times_are_fixed_plus_per_unit_of_work(commands, regions, pixels, frames, candidates,
                                                        measurements, checks, packets, samples) -> None:
    """Each task's time is its fixed cost plus its per-unit costs times the work it reports, and nothing else."""
    c = TimingConfig()
    w = Work(commands=commands, regions=regions, foreground_px=pixels, frames=frames, candidates=candidates,
             measurements=measurements, checks=checks, packets=packets, limb_samples=samples)
    expected = {
        Task.TIME: c.time_s,
        Task.TELECOMMANDS: c.telecommand_s * commands,
        Task.SCHEDULE: c.schedule_s + c.telecommand_s * commands,
        Task.ATTITUDE: c.attitude_s,
        Task.IMAGING: c.imaging_s * frames + c.imaging_s_per_region * regions
        + c.imaging_s_per_foreground_pixel * pixels + c.fpga_limb_s_per_sample * samples,
        Task.RECOGNITION: c.recognition_s + c.recognition_s_per_candidate * candidates
        + c.recognition_s_per_measurement * measurements,
        Task.MODES: c.modes_s,
        Task.CONTROL: c.control_s,
        Task.FDIR: c.fdir_s + c.fdir_s_per_check * checks + c.telecommand_s * commands,
        Task.CAMERA: c.camera_s,
        Task.TELEMETRY: c.telemetry_s + c.telemetry_s_per_packet * packets,
    }
    model = TimingModel(c)
    off = TimingModel(c.model_copy(update={"modelled": False}))
    for task in Task:
        assert model.execution_s(task, w) == pytest.approx(expected[task], rel=1e-12, abs=0.0)
        assert off.execution_s(task, w) == 0.0
