"""The saved frames: an even choice of them, and the animated GIF thinned to its frame and byte budgets."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from analysis.frames import flyby_gif, spread_ids
from analysis.runfolder import load_run
from ground.config import ReportConfig
from tests.analysis.synthetic import CA_OBT, SAVED_FRAME_KS


def test_gif_has_one_frame_per_saved_png(full_run) -> None:
    """With fewer saved frames than gif_max_frames, the GIF shows each of them once."""
    run, _, _ = full_run
    with Image.open(run / "report" / "flyby.gif") as gif:
        assert gif.n_frames == len(SAVED_FRAME_KS)
        assert gif.size == (512, 512)


def test_gif_is_thinned_to_max_frames_and_bytes(full_run, tmp_path) -> None:
    """gif_max_frames caps the frame count; a byte budget thins the frames until the file fits."""
    run, _, _ = full_run
    data = load_run(run)
    gif, n = flyby_gif(data, CA_OBT, ReportConfig(gif_max_frames=6))
    assert n == 6
    (tmp_path / "six.gif").write_bytes(gif)
    with Image.open(tmp_path / "six.gif") as im:
        assert im.n_frames == 6
    budget = len(gif) // 2
    small, m = flyby_gif(data, CA_OBT, ReportConfig(gif_max_frames=6, gif_max_bytes=budget))
    assert len(small) <= budget and m < 6


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 500), count=st.integers(1, 40))
def test_spread_ids_is_an_even_subset(n: int, count: int) -> None:
    """spread_ids keeps min(n, count) sorted distinct ids, first and last included."""
    ids = list(range(5, 5 + 3 * n, 3))
    got = spread_ids(ids[::-1], count)
    assert len(got) == min(n, count)
    assert got == sorted(set(got)) and set(got) <= set(ids)
    assert got[0] == ids[0] and (count == 1 or got[-1] == ids[-1])
