"""The navigation report (TM[200,130]) round-trips through its packet and spacepackets accepts it."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st
from spacepackets.ecss import PusTm

from contracts import pus

px = st.floats(0, 2048, width=32)
opt_pair = st.none() | st.tuples(px, px)


@given(frame_id=st.integers(0, 2**32 - 1), dim=opt_pair, did=opt_pair, area=st.integers(0, 2**32 - 1),
       los=st.none() | st.sampled_from([(1.0, 0.0, 0.0), (0.0, 0.6, 0.8), (-0.48, 0.6, 0.64)]))
def test_round_trip(frame_id: int, dim: tuple | None, did: tuple | None, area: int, los: tuple | None) -> None:
    """decode(encode(report)) is the report, absent fields included."""
    r = pus.NavigationReport(frame_id=frame_id, dimorphos_col_row=dim, didymos_col_row=did, dimorphos_area_px=area,
                             los_inertial=los)
    raw = pus.encode_tm(r, 0x0C1, 7, 1000.5, 3)
    header, back = pus.decode_tm(raw)
    assert back == r
    assert (header.service, header.subservice) == (200, 130)
    assert PusTm.unpack(raw, timestamp_len=pus.CUC_LEN).service == 200


est = st.floats(-1e9, 1e9, allow_nan=False)


@given(n=st.integers(0, 2**32 - 1), grid=st.none() | st.tuples(est, est, est),
       cont=st.none() | st.tuples(est, est, est, est))
def test_estimate_report_round_trip(n: int, grid: tuple | None, cont: tuple | None) -> None:
    """The C/A estimate report round-trips, each estimate present or absent as a whole."""
    g = grid or (None, None, None)
    c = cont or (None, None, None, None)
    r = pus.EstimateReport(n_measurements=n, grid_ca_obt_s=g[0], grid_ca_distance_km=g[1], grid_mse_rad2=g[2],
                           continuous_ca_obt_s=c[0], continuous_ca_distance_km=c[1], continuous_sigma_time_s=c[2],
                           continuous_sigma_distance_km=c[3])
    header, back = pus.decode_tm(pus.encode_tm(r, 0x0C1, 1, 5.0, 0))
    assert back == r
    assert (header.service, header.subservice) == (200, 131)
