"""The on-board timing model: how long each task and imaging stage takes on the modelled on-board computer.

LICIACube's navigation ran on the Argotec FERMI on-board computer (the LICIACube navigation paper, "Imaging
Subsystem"): binning with 8-bit compression, binarisation and region labelling (the paper's steps 1 to 3) in its
FPGA, feature extraction (area and centroid of the regions, step 4) and the rest of the flight software on a
dual-core SPARC-V8 processor. The paper gives no execution times. The defaults below are estimates for that
hardware, each with its basis: a LEON3-class SPARC-V8 core with a floating-point unit at 50 MHz (the navigation
tasks on one core), the FPGA handling one binned pixel per clock at 50 MHz, the camera on a SpaceWire link.

A task's execution time is a fixed time plus a time per unit of the work it reports (``Work``: telecommands,
regions, foreground pixels, recognition candidates, measurements, packets), for the nominal processor; the
processor's slow-down factor, a hardware reading, multiplies it in the executive. A frame reaches the software
after the rest of its exposure, its readout over the camera link and the FPGA stages, plus any delay the hardware
reports (the universe's imaging_latency fault). ``modelled: false`` gives the zero-time flight software: no task or
stage takes time, so every measurement is used in the control period of its exposure.

This is the processor model of the OBSW node (the emulated hardware), not flight logic: no flight decision reads
it, overruns are found by the executive from the execution times it gives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pydantic import Field

from contracts.model import Config
from contracts.task import Task

_LEON = "a LEON3-class SPARC-V8 core with FPU at 50 MHz (the LICIACube navigation paper: dual-core SPARC-V8; " \
        "clock and cycle count are this model's estimate)"


class TimingConfig(Config):
    """Execution times of the tasks and imaging stages on the modelled on-board computer, and the camera link."""

    modelled: bool = Field(
        True, description="False: every task and imaging stage takes no on-board time (the zero-time flight "
        "software; a delay the hardware reports still applies)"
    )
    camera_link_rate_bps: float = Field(
        80e6, gt=0, description="effective data rate of the camera-to-computer link, bit/s: a 100 Mbit/s SpaceWire "
        "link (ECSS-E-ST-50-12C) carries 8 data bits in each 10-bit data character (the paper does not name the "
        "link); a 1024x1024 12-bit frame takes 0.157 s"
    )
    fpga_filtering_s_per_binned_pixel: float = Field(
        0.0, ge=0, description="FPGA binning and 8-bit compression after the last pixel has arrived, s per binned "
        "pixel (0: they run on the pixels as they arrive, so they end with the readout)"
    )
    fpga_binarisation_s_per_binned_pixel: float = Field(
        20e-9, ge=0, description="FPGA binarisation, s per binned pixel: one pass over the binned image once the "
        "histogram's threshold is known, one pixel per clock at 50 MHz (estimate)"
    )
    fpga_labelling_s_per_binned_pixel: float = Field(
        40e-9, ge=0, description="FPGA region labelling, s per binned pixel: two passes (provisional labels and "
        "their equivalences, then relabelling), one pixel per clock at 50 MHz (estimate)"
    )
    fpga_limb_s_per_sample: float = Field(
        20e-9, ge=0, description="FPGA limb fit of Dimorphos (obsw/imaging_limb.py), s per gradient sample: the "
        "software hands the FPGA the search window and waits; a pipelined sampler (bilinear gradient, radial "
        "projection, running median) takes one sample per clock at 50 MHz (estimate); up to 0.8 million samples, "
        "16 ms, a fit in the nominal flyby (Dimorphos 28 px across)"
    )
    time_s: float = Field(50e-6, ge=0, description=f"time management (OBT jump check, time report), s: 2,500 "
                          f"cycles of {_LEON}")
    telecommand_s: float = Field(
        0.4e-3, ge=0, description=f"one telecommand, received or released by the schedule, s: decoding, CRC-16 of "
        f"up to 1 kB, execution and its verification reports, 20,000 cycles of {_LEON}"
    )
    schedule_s: float = Field(50e-6, ge=0, description=f"schedule check when a tag is due, s: 2,500 cycles of {_LEON}")
    attitude_s: float = Field(
        0.6e-3, ge=0, description=f"attitude determination, s: the multiplicative EKF's propagation and star tracker "
        f"update (6-state covariance, 3x3 gain) and the wheel momenta, 30,000 cycles of {_LEON}"
    )
    imaging_s: float = Field(0.3e-3, ge=0, description=f"software stage of the imaging chain per frame, s: "
                             f"identification and line of sight, 15,000 cycles of {_LEON}")
    imaging_s_per_region: float = Field(
        30e-6, ge=0, description=f"feature extraction per labelled region, s: area, centroid, box, moments and the "
        f"identification tests, 1,500 cycles of {_LEON}"
    )
    imaging_s_per_foreground_pixel: float = Field(
        0.4e-6, ge=0, description=f"feature extraction per foreground pixel, s: accumulating its moments, 20 cycles "
        f"of {_LEON}"
    )
    recognition_s: float = Field(0.1e-3, ge=0, description=f"trajectory recognition per run, s: 5,000 cycles of "
                                 f"{_LEON}")
    recognition_s_per_candidate: float = Field(
        4e-6, ge=0, description=f"grid update per candidate trajectory and new measurement, s: an atan2 and a capped "
        f"squared residual, 200 cycles of {_LEON}"
    )
    recognition_s_per_measurement: float = Field(
        15e-6, ge=0, description=f"continuous estimate per measurement held, s, each time it is solved again: the "
        f"predictions, Jacobian rows and normal equations of its few Gauss-Newton iterations, 750 cycles of {_LEON}"
    )
    modes_s: float = Field(50e-6, ge=0, description=f"mode manager, s: 2,500 cycles of {_LEON}")
    control_s: float = Field(
        0.8e-3, ge=0, description=f"tracking loop and PD control, s: the loop's matrix exponential, two rotation "
        f"matrices, the control law and the wheel allocation, 40,000 cycles of {_LEON}"
    )
    fdir_s: float = Field(0.1e-3, ge=0, description=f"FDIR each minor frame, s: the wheel failure detector and the "
                          f"service 12 checks of a few definitions, 5,000 cycles of {_LEON}")
    fdir_s_per_check: float = Field(50e-6, ge=0, description=f"FDIR per failed parameter check or check transition "
                                    f"handled, s: its event report, 2,500 cycles of {_LEON}")
    camera_s: float = Field(20e-6, ge=0, description=f"camera commanding, s: 1,000 cycles of {_LEON}")
    telemetry_s: float = Field(50e-6, ge=0, description=f"telemetry task, s: 2,500 cycles of {_LEON}")
    telemetry_s_per_packet: float = Field(
        0.25e-3, ge=0, description=f"one report packet, s: encoding about 200 octets and their CRC-16, 12,500 "
        f"cycles of {_LEON}"
    )


@dataclass(frozen=True, slots=True)
class Work:
    """What one run of a task did, in the units its execution time depends on."""

    commands: int = 0  # telecommands executed
    regions: int = 0  # labelled regions given to feature extraction
    foreground_px: int = 0  # pixels of those regions
    frames: int = 0  # frames processed
    candidates: int = 0  # grid candidates updated (candidates x new measurements)
    measurements: int = 0  # measurements in a continuous solve (0: not solved)
    checks: int = 0  # failed parameter checks and check transitions handled
    packets: int = 0  # report packets built
    limb_samples: int = 0  # gradient samples of the FPGA's limb fit (obsw.imaging_limb)


NO_WORK = Work()  # a task's run with nothing counted (one shared value: a frozen Work costs 2 us to build)


class TimingModel:
    """Execution times on the nominal processor and the delay from a frame's exposure to the software."""

    def __init__(self, cfg: TimingConfig) -> None:
        self.cfg = cfg
        c = cfg
        # each task's cost as a function of its work, looked up per run (eleven runs a control period)
        self._costs: dict[Task, Callable[[Work], float]] = {
            Task.TIME: lambda w: c.time_s,
            Task.TELECOMMANDS: lambda w: c.telecommand_s * w.commands,
            Task.SCHEDULE: lambda w: c.schedule_s + c.telecommand_s * w.commands,
            Task.ATTITUDE: lambda w: c.attitude_s,
            Task.IMAGING: lambda w: (c.imaging_s * w.frames + c.imaging_s_per_region * w.regions
                                     + c.imaging_s_per_foreground_pixel * w.foreground_px
                                     + c.fpga_limb_s_per_sample * w.limb_samples),
            Task.RECOGNITION: lambda w: (c.recognition_s + c.recognition_s_per_candidate * w.candidates
                                         + c.recognition_s_per_measurement * w.measurements),
            Task.MODES: lambda w: c.modes_s,
            Task.CONTROL: lambda w: c.control_s,
            # with the telecommands of the event actions it runs
            Task.FDIR: lambda w: c.fdir_s + c.fdir_s_per_check * w.checks + c.telecommand_s * w.commands,
            Task.CAMERA: lambda w: c.camera_s,
            Task.TELEMETRY: lambda w: c.telemetry_s + c.telemetry_s_per_packet * w.packets,
        }
        if not c.modelled:
            self._costs = {t: lambda w: 0.0 for t in Task}

    def execution_s(self, task: Task, work: Work) -> float:
        """How long ``task`` takes for ``work`` on the nominal processor, s."""
        return self._costs[task](work)

    def frame_delay_s(self, width_px: int, height_px: int, bit_depth: int, exposure_s: float,
                      binned_px: int) -> float:
        """From a frame's time stamp (mid-exposure) to the end of the FPGA stages, s: the rest of the exposure, the
        readout over the camera link and binning, binarisation and labelling of its ``binned_px`` pixels."""
        c = self.cfg
        if not c.modelled:
            return 0.0
        readout = width_px * height_px * bit_depth / c.camera_link_rate_bps
        fpga = binned_px * (c.fpga_filtering_s_per_binned_pixel + c.fpga_binarisation_s_per_binned_pixel
                            + c.fpga_labelling_s_per_binned_pixel)
        return 0.5 * exposure_s + readout + fpga
