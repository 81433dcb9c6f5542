import math

import pytest
from fieldrx_edge.gnss import Fix
from fieldrx_edge.job_package import ControllerSettings
from fieldrx_edge.metering import calibration_from_dict, shaft_rpm_for_rate
from fieldrx_edge.motor import MotorLoop, build_controller, closed_loop_t50_s, simulated_motor
from fieldrx_edge.protocol import TelemetryRecord
from fieldrx_edge.runtime import Measured, Pipeline, RuntimeConfig, make_record

from .jobfactory import holed_field, trial_plot

OX, OY = 500_000.0, 5_800_000.0
EAST = 90.0


def pipe(job=None, **kw):
    return Pipeline(job or trial_plot(), RuntimeConfig(**kw))


def test_metering_target_follows_the_cell_rate():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    d = p.on_position(0.0, OX + 2.5, OY + 1.15, 2.0, EAST)
    assert d.metering and d.cell == 0 and d.cell_seq == job.seq[0]
    assert d.target_rate_kg_ha == job.rate_kg_ha[0]
    cal = calibration_from_dict(job.calibration)
    assert d.target_rpm == pytest.approx(shaft_rpm_for_rate(cal, job.rate_kg_ha[0], 2.3, 2.0))


def test_lag_look_ahead_moves_the_decision_point_forward():
    job = trial_plot()
    p = pipe(job, lag_compensation=True, response_s=0.0, gnss_period_s=0.0)
    d = p.on_position(0.0, OX + 1.0, OY + 1.15, 2.0, EAST)
    assert d.lx == pytest.approx(OX + 1.0 + 2.0 * job.lag_s, abs=1e-6)  # eq. 16: v * T_lag
    assert d.cell == 0 if 1.0 + 2.0 * job.lag_s < 5 else d.cell == 1


def test_stops_outside_field_in_hole_and_when_raised():
    job = holed_field()
    p = pipe(job, lag_compensation=False)
    assert p.on_position(0.0, OX - 1.0, OY + 1.15, 2.0, EAST).reason == "outside_field"
    d = p.on_position(0.1, OX + 30.0, OY + 11.0, 2.0, EAST)
    assert not d.metering and d.reason == "hole" and "outside_field" in d.alarms
    d = p.on_position(0.2, OX + 2.0, OY + 1.15, 2.0, EAST, implement_down=False)
    assert not d.metering and d.reason == "implement_raised"
    assert p.on_position(0.3, OX + 2.0, OY + 1.15, 2.0, EAST).metering


def test_overlap_control_skips_applied_cells_and_can_be_disabled():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    for k in range(60):  # drive cell 0 then cell 1
        p.on_position(k * 0.1, OX + 0.5 + k * 0.15, OY + 1.15, 1.5, EAST)
    assert p.locator.finished[0]
    d = p.on_position(7.0, OX + 2.0, OY + 1.15, 1.5, EAST + 180)  # drive back into cell 0
    assert not d.metering and d.reason == "already_applied"
    job.overlap_control = False
    p2 = pipe(job, lag_compensation=False)
    p2.locator.finished[0] = True
    assert p2.on_position(0.0, OX + 2.0, OY + 1.15, 1.5, EAST).metering


def test_border_jitter_does_not_finish_a_cell_early():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    p.on_position(0.0, OX + 4.9, OY + 1.15, 1.5, EAST)
    p.on_position(0.1, OX + 5.05, OY + 1.15, 1.5, EAST)  # into cell 1, cell 0 finished
    d = p.on_position(0.2, OX + 4.95, OY + 1.15, 1.5, EAST)  # noise: back over the border
    assert d.metering and d.cell == 1
    assert not p.locator.finished[1]


def test_fix_loss_holds_then_stops():
    job = trial_plot()
    job.fix_loss_hold_s = 2.0
    p = pipe(job, lag_compensation=False)
    d0 = p.on_position(10.0, OX + 2.0, OY + 1.15, 1.5, EAST)
    assert d0.metering
    bad = Fix(lat=52.0, lon=15.0, fix_quality=0, rmc_status="V")
    d = p.on_fix(bad, 11.0)
    assert d.metering and d.reason == "fix_lost_hold" and "fix_lost" in d.alarms
    assert d.target_rpm == d0.target_rpm
    d = p.on_no_fix(12.5)
    assert not d.metering and d.reason == "fix_lost"
    d = p.on_position(13.0, OX + 2.5, OY + 1.15, 1.5, EAST)
    assert d.metering  # fix back: metering resumes (cell 0 was not finished by the hold)


def test_shaft_range_alarms_and_clamp():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    d = p.on_position(0.0, OX + 2.0, OY + 1.15, 0.3, EAST)  # creeping: below 30 r/min
    assert "shaft_below_range" in d.alarms and d.target_rpm == 30.0
    assert "speed_out_of_range" in d.alarms
    p = pipe(job, lag_compensation=False)
    d = p.on_position(0.0, OX + 2.0, OY + 1.15, 4.0, EAST)  # too fast: above 130 r/min
    assert "shaft_above_range" in d.alarms and d.target_rpm == 130.0


def test_kalman_filters_speed():
    p = pipe(lag_compensation=False)
    vals = [1.5 + (0.12 if i % 2 else -0.12) for i in range(50)]
    out = [
        p.on_position(i * 0.1, OX + 2 + i * 0.01, OY + 1.15, v, EAST).speed_m_s
        for i, v in enumerate(vals)
    ]
    assert out[0] == pytest.approx(vals[0])  # initialised from the first measurement
    assert max(abs(v - 1.5) for v in out[20:]) < 0.05


def test_record_is_a_valid_telemetry_record():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    fx = Fix(
        t=1_763_700_000.0,
        lat=52.3,
        lon=15.0,
        fix_quality=4,
        hdop=0.7,
        speed_m_s=1.5,
        course_deg=EAST,
        rmc_status="A",
    )
    fx.x, fx.y = OX + 2.0, OY + 1.15
    d = p.on_fix(fx, 0.0)
    r = make_record(p, d, fx, Measured(100.0, 80.0, True, fx.t))
    r["seq"] = 1
    rec = TelemetryRecord.from_dict(r)
    assert rec.cell_seq == job.seq[0] and rec.target_rate_kg_ha == job.rate_kg_ha[0]
    assert rec.applied_rate_kg_ha > 0


def test_motor_loop_tracks_setpoint_with_ladrc():
    m = MotorLoop(build_controller(ControllerSettings("ladrc")), simulated_motor(0.01), 0.01)
    m.setpoint_rpm = 100.0
    for _ in range(100):
        m.step()
    assert abs(m.rpm - 100.0) < 0.5
    assert 0 < closed_loop_t50_s(ControllerSettings("ladrc")) < 0.1
    for name in ("pid", "incremental_pid", "fuzzy_pid"):
        c = build_controller(ControllerSettings(name))
        assert math.isfinite(c.step(50.0, 0.0, 0.01))


def test_saturated_motor_raises_alarm():
    job = trial_plot()
    p = pipe(job, lag_compensation=False)
    d = p.on_position(0.0, OX + 2.0, OY + 1.15, 2.0, EAST)
    assert "motor_saturated" in make_record(p, d, None, Measured(50.0, 100.0, True, 1.0))["alarms"]
    assert (
        "motor_saturated" not in make_record(p, d, None, Measured(50.0, 60.0, True, 1.0))["alarms"]
    )


def test_early_start_meters_before_the_landing_point_enters():
    job = trial_plot()
    cfg = dict(lag_compensation=True, response_s=0.0, gnss_period_s=0.0)
    x = OX - 2.0 * job.lag_s - 0.1  # landing point 0.1 m before the field edge
    plain = pipe(job, **cfg).on_position(0.0, x, OY + 1.15, 2.0, EAST)
    assert not plain.metering and plain.reason == "outside_field"
    early = pipe(job, start_extra_s=0.1, **cfg).on_position(0.0, x, OY + 1.15, 2.0, EAST)
    assert early.metering and early.reason == "start_ahead" and early.cell == 0


def test_edge_stop_anticipates_the_coast_down():
    job = trial_plot()
    cfg = dict(lag_compensation=True, response_s=0.0, gnss_period_s=0.0)
    x = OX + 35.0 - 2.0 * job.lag_s - 0.1  # landing point 0.1 m before the far edge
    assert pipe(job, **cfg).on_position(0.0, x, OY + 1.15, 2.0, EAST).metering
    d = pipe(job, stop_extra_s=0.1, **cfg).on_position(0.0, x, OY + 1.15, 2.0, EAST)
    assert not d.metering and d.reason == "edge_ahead"


def test_agent_records_carry_fix_time_and_period_and_never_a_nan(tmp_path):
    """A record's t is the receiver's fix time and fix_period_s the fix interval,
    however fast the lines arrive. a GGA with HDOP 'nan' never puts a NaN in the
    queue (the batch on the wire is strict JSON)."""
    import json

    from fieldrx_edge.runtime import Agent
    from fieldrx_edge.sim import nmea
    from fieldrx_edge.uplink import TelemetryQueue

    class Motor:
        rpm = 0.0
        duty = 0.0
        setpoint_rpm = 0.0

    job = trial_plot()
    q = TelemetryQueue(tmp_path / "q.sqlite", job.machine_id)
    agent = Agent(job, q, Motor(), RuntimeConfig())
    t0 = 1_763_700_000.0
    for i in range(20):
        t, lat, lon = t0 + 0.1 * i, 52.3 + 1e-6 * i, 15.0
        gga = nmea.gga(t, lat, lon, hdop=float("nan") if i == 7 else 0.7)
        agent.handle_line(gga)
        agent.handle_line(nmea.rmc(t, lat, lon, 1.5, 0.0))
    body, n, _ = q.pending_batch(100)
    recs = json.loads(body, parse_constant=lambda c: pytest.fail(f"{c} on the wire"))["records"]
    assert n == 20
    assert [r["t"] for r in recs] == pytest.approx([t0 + 0.1 * i for i in range(20)], abs=0.006)
    assert recs[0]["fix_period_s"] is None
    assert all(r["fix_period_s"] == pytest.approx(0.1, abs=0.011) for r in recs[1:])
    assert recs[7]["hdop"] is None and recs[8]["hdop"] == 0.7
