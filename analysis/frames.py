"""The saved camera frames of a run: which to show, where the detected and true bodies fall on them, and the
animated GIF of the flyby (pillow)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from ground.config import ReportConfig
from analysis.page import Section
from analysis.runfolder import RunData, load_run
from analysis.scoring import RunFigures, binned_px


def spread_ids(ids: Sequence[int], count: int) -> list[int]:
    """At most ``count`` of ``ids`` (sorted), evenly spread from the first to the last."""
    ids = sorted(ids)
    if len(ids) <= count:
        return ids
    picks = np.unique(np.round(np.linspace(0, len(ids) - 1, count)).astype(int))
    return [ids[i] for i in picks]


def frame_marks(data: RunData, frame_id: int, png_side: int) -> dict[str, tuple[float, float] | None]:
    """Detected and true Dimorphos/Didymos positions of a frame, in the PNG's pixel coordinates."""
    marks: dict[str, tuple[float, float] | None] = dict.fromkeys(("det_dim", "det_did", "true_dim", "true_did"))
    n_bin = data.scenario.obsw.imaging.binned_size_px
    if data.telemetry is not None:
        for _, nav in data.telemetry.navigation:
            if nav.frame_id == frame_id:
                k = png_side / n_bin
                # binned pixel centres map to PNG pixel centres: same binning formula with factor 1/k
                if nav.dimorphos_col_row is not None:
                    marks["det_dim"] = tuple(binned_px(np.asarray(nav.dimorphos_col_row), 1 / k))
                if nav.didymos_col_row is not None:
                    marks["det_did"] = tuple(binned_px(np.asarray(nav.didymos_col_row), 1 / k))
    truth = data.truth
    if truth is not None:
        rows = np.flatnonzero(truth.frame_id == frame_id)
        if rows.size:
            b = data.scenario.universe.camera.resolution_px / png_side
            for key, px in (("true_dim", truth.dimorphos_px[rows[0]]), ("true_did", truth.didymos_px[rows[0]])):
                if np.all(np.isfinite(px)):
                    marks[key] = tuple(binned_px(px, b))
    return marks


def frame_obt_s(data: RunData, frame_id: int) -> float | None:
    """OBT of a frame's exposure, from the truth or else its NavigationReport; None if neither has it."""
    if data.truth is not None:
        rows = np.flatnonzero(data.truth.frame_id == frame_id)
        if rows.size:
            return float(data.truth.obt_s[rows[0]])
    if data.telemetry is not None:
        for t, nav in data.telemetry.navigation:
            if nav.frame_id == frame_id:
                return t
    return None


def load_gray(path: Path) -> NDArray[np.uint8]:
    """A frame PNG as 8-bit grey levels."""
    with Image.open(path) as im:
        return np.asarray(im.convert("L"))


_GRAYS = 250  # palette 0..249 grey levels, then the marker colours
_RED, _GREEN, _ORANGE, _CYAN, _WHITE = 250, 251, 252, 253, 254


def _palette() -> list[int]:
    grays = [round(i * 255 / (_GRAYS - 1)) for i in range(_GRAYS)]
    pal = [c for g in grays for c in (g, g, g)]
    pal += [255, 0, 0, 0, 255, 0, 255, 165, 0, 0, 255, 255, 255, 255, 255, 0, 0, 0]
    return pal


def gif_frame(data: RunData, frame_id: int, ca_obt_s: float) -> Image.Image:
    """One animation frame: the PNG in a fixed grey palette with the marks and a time label."""
    gray = load_gray(data.frames[frame_id])
    lut = np.round(np.arange(256) * (_GRAYS - 1) / 255).astype(np.uint8)
    im = Image.fromarray(lut[gray], mode="P")
    im.putpalette(_palette())
    draw = ImageDraw.Draw(im)
    m = frame_marks(data, frame_id, gray.shape[1])
    r = 7
    if m["true_dim"] is not None:
        x, y = m["true_dim"]
        draw.ellipse((x - r, y - r, x + r, y + r), outline=_GREEN)
    if m["true_did"] is not None:
        x, y = m["true_did"]
        draw.ellipse((x - 2 * r, y - 2 * r, x + 2 * r, y + 2 * r), outline=_CYAN)
    if m["det_dim"] is not None:
        x, y = m["det_dim"]
        draw.line((x - r, y, x + r, y), fill=_RED)
        draw.line((x, y - r, x, y + r), fill=_RED)
    if m["det_did"] is not None:
        x, y = m["det_did"]
        draw.line((x - r, y - r, x + r, y + r), fill=_ORANGE)
        draw.line((x - r, y + r, x + r, y - r), fill=_ORANGE)
    obt = frame_obt_s(data, frame_id)
    label = f"frame {frame_id}" + ("" if obt is None else f"  C/A{obt - ca_obt_s:+.1f} s")
    draw.text((6, 6), label, fill=_WHITE)
    return im


def flyby_gif(data: RunData, ca_obt_s: float, cfg: ReportConfig) -> tuple[bytes, int]:
    """The animated GIF of the saved frames with detections drawn, and its frame count.

    At most ``gif_max_frames`` frames evenly spread, fewer until the file is under ``gif_max_bytes``.
    """
    count = cfg.gif_max_frames
    drawn: dict[int, Image.Image] = {}  # a thinner retry reuses the frames already drawn
    while True:
        ids = spread_ids(list(data.frames), count)
        for fid in ids:
            if fid not in drawn:
                drawn[fid] = gif_frame(data, fid, ca_obt_s)
        frames = [drawn[fid] for fid in ids]
        buf = io.BytesIO()
        frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=cfg.gif_frame_ms,
                       loop=0, disposal=1)
        if buf.tell() <= cfg.gif_max_bytes or len(ids) == 1:
            return buf.getvalue(), len(ids)
        # frames cost about the same each: scale the count to the budget, with 5% margin
        count = max(1, min(len(ids) - 1, int(len(ids) * 0.95 * cfg.gif_max_bytes / buf.tell())))


def gif_section(data: RunData, figs: RunFigures, cfg: ReportConfig) -> Section:
    """The animated GIF, written to report/flyby.gif and shown from there."""
    s = Section("The flyby as the camera saw it", "Animated frames with the same marks as the mosaic "
                "(report/flyby.gif, beside this page).")
    if not data.frames:
        s.missing.append("no frame PNGs in frames/: no animation")
        return s
    gif, n = flyby_gif(data, figs.true_ca_obt_s, cfg)
    out = data.run_dir / "report" / "flyby.gif"
    out.parent.mkdir(exist_ok=True)
    out.write_bytes(gif)
    s.html_body = "<img alt='flyby animation' src='report/flyby.gif'>"
    s.notes.append(f"{n} of {len(data.frames)} saved frames, {len(gif) / 1e6:.1f} MB")
    return s


def gif_section_of(run_dir: Path, figs: RunFigures, cfg: ReportConfig) -> Section:
    """``gif_section`` of the run folder ``run_dir``, loaded here: what the report's helper process runs (this module
    does not import matplotlib, so the helper starts in half the time)."""
    return gif_section(load_run(run_dir), figs, cfg)
