"""On the tractor: turning at the headland with the implement raised is
not an alarm. The pipeline flagged speed_out_of_range (turns are slow) and outside_field
(the look-ahead leaves the field) on every turn, and the fleet marker turned red."""

from __future__ import annotations

from fieldrx_edge.runtime import Pipeline, RuntimeConfig

from .jobfactory import trial_plot

OX, OY = 500_000.0, 5_800_000.0


def test_raised_implement_raises_no_speed_or_edge_alarm() -> None:
    job = trial_plot()
    slow = 0.5 * job.speed_min_m_s
    p = Pipeline(job, RuntimeConfig(lag_compensation=False))
    d = p.on_position(0.0, OX - 3.0, OY + 1.15, slow, 270.0, implement_down=False)
    assert not d.metering and d.alarms == []
    p = Pipeline(job, RuntimeConfig(lag_compensation=False))
    d = p.on_position(0.0, OX - 3.0, OY + 1.15, slow, 270.0, implement_down=True)
    assert set(d.alarms) == {"speed_out_of_range", "outside_field"}  # lowered: both count
