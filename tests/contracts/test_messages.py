"""Bus messages round-trip exactly, and a bad message gives a DecodeError naming what was wrong."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from contracts.errors import DecodeError
from contracts.messages import SensorData, StepReply, StepRequest, TruthRecord, decode, encode

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(
    step=st.integers(0, 2**40),
    obt=finite,
    gyro=st.tuples(finite, finite, finite),
    uplink=st.lists(st.binary(max_size=64), max_size=4).map(tuple),
    blob=st.binary(max_size=256),
)
def test_step_request_round_trips(step: int, obt: float, gyro: tuple, uplink: tuple, blob: bytes) -> None:
    """decode(encode(m, blob)) gives back m and blob exactly."""
    msg = StepRequest(
        step=step, obt_s=obt, sensors=SensorData(star_tracker_q=None, gyro_rad_s=gyro, wheel_speed_rad_s=(1.0,)),
        uplink=uplink,
    )
    back, b = decode(StepRequest, encode(msg, blob))
    assert back == msg
    assert b == blob


def test_truncated_message_names_type() -> None:
    """A message shorter than its header length is refused with the message type named."""
    data = encode(StepReply(step=1, wheel_torque_nm=(0.0, 0.0, 0.0)))
    with pytest.raises(DecodeError, match="StepReply: header says"):
        decode(StepReply, data[:10])


def test_wrong_version_names_field() -> None:
    """A message of another bus version is refused, naming the version field."""
    data = encode(StepReply(step=1, wheel_torque_nm=(0.0,))).replace(b'"version":1', b'"version":7')
    with pytest.raises(DecodeError, match="StepReply: version"):
        decode(StepReply, data)


def test_garbage_is_refused() -> None:
    """Random bytes are a DecodeError, never another exception."""
    with pytest.raises(DecodeError):
        decode(StepReply, b"\x00\x00\x00\x05hello")


def test_trusted_makes_what_validation_makes_of_valid_values() -> None:
    """``Frozen.trusted`` of values of the fields' types equals the validated model: values, fields set, field order,
    JSON; an unknown or a missing field is refused."""
    values = dict(t_s=1.5, obt_s=2.5, q=(0.0, 0.0, 0.6, 0.8), omega_rad_s=(0.1, 0.2, 0.3),
                  wheel_momentum_nms=(0.0,) * 4, wheel_torque_nm=(1e-3, 0.0, -1e-3, 0.0), pointing_error_rad=0.01, target_in_fov=True, range_m=5e4,
                  theta_rad=1.2, phase_angle_deg=60.0, dimorphos_px=(511.5, 3.25))
    trusted, validated = TruthRecord.trusted(**values), TruthRecord(**values)
    assert trusted == validated and trusted.model_dump_json() == validated.model_dump_json()
    assert trusted.model_fields_set == validated.model_fields_set == set(values)
    assert list(trusted.__dict__) == list(validated.__dict__) == list(TruthRecord.model_fields)
    # the records trusted with the same fields share their set of them: a copy with more fields leaves it alone
    other = TruthRecord.trusted(**values)
    copied = other.model_copy(update={"frame_id": 3})
    assert copied.model_fields_set == set(values) | {"frame_id"} and trusted.model_fields_set == set(values)
    with pytest.raises(TypeError, match="unknown fields \\['colour'\\]"):
        TruthRecord.trusted(**values, colour=1.0)
    with pytest.raises(TypeError, match="missing fields \\['t_s'\\]"):
        TruthRecord.trusted(**{k: v for k, v in values.items() if k != "t_s"})
