"""Properties every controller must keep for any input: clamped, finite output."""

from __future__ import annotations

import math

import pytest
from fieldrx_edge.control import make_controller
from hypothesis import given, settings
from hypothesis import strategies as st

# hypothesis searches hundreds of cases per test: minutes, not seconds (make check skips)
pytestmark = pytest.mark.slow

CONFIGS = {
    "pid": {"kp": 2.0, "ki": 20.0, "kd": 0.05},
    "isp": {},
    "ladrc": {"wc": 20.0, "wo": 100.0, "b0": 8.892},
    "fuzzy_pid": {"kp": 12.0, "ki": 0.05, "kd": 3.0},
}

signal = st.floats(-1e4, 1e4, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(
    st.sampled_from(sorted(CONFIGS)),
    st.lists(st.tuples(signal, signal), min_size=1, max_size=60),
    st.floats(-50.0, 0.0),
    st.floats(0.0, 50.0),
)
def test_output_always_within_limits(
    name: str, inputs: list[tuple[float, float]], lo: float, hi: float
) -> None:
    c = make_controller(name, **CONFIGS[name], out_min=lo, out_max=hi)
    for r, y in inputs:
        u = c.step(r, y, 0.002)
        assert lo <= u <= hi and math.isfinite(u)
    assert c.output == u
