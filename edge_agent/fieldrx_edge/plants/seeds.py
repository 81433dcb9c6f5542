"""The three papers' plants, discretised (exact ZOH) for simulation and tests.

Every factory returns a ``DiscretePlant`` with actuator limits and an input
disturbance slot (``plant.disturbance``). Modelling choices that the papers
leave open are stated here and in docs/science.md.
"""

from __future__ import annotations

import math

from fieldrx_edge.plants.lti import DiscretePlant

# Seed 001 eq. 4: PWM duty -> metering-disc shaft speed, identified in Matlab.
SEED001_NUM = (8.892, 0.04603)
SEED001_DEN = (1.0, 6.699, 0.03441)


def seed001_motor(dt: float, *, u_min: float = -math.inf, u_max: float = math.inf) -> DiscretePlant:
    """Seed 001 eq. 4, G(s) = (8.892 s + 0.04603) / (s^2 + 6.699 s + 0.03441).

    Its pole at -0.00514 nearly cancels the zero at -0.00518, so it behaves as
    8.892 / (s + 6.694): first order with b = 8.892 and DC gain 1.338.
    Unlimited by default, as in the paper's unit-step simulation.
    """
    return DiscretePlant.from_tf(
        SEED001_NUM, SEED001_DEN, dt, u_min=u_min, u_max=u_max, name="seed001_motor"
    )


# Seed 000 eq. 3, 8-10 and the motor data under eq. 7.
SEED000_DRIVER_GAIN = 2.4
SEED000_DEAD_TIME_S = 0.01
SEED000_REDUCER = 0.028
SEED000_FEEDBACK = 8.0
SEED000_LA_H = 0.62e-3
SEED000_RM_OHM = 0.5
SEED000_CE = 0.052
SEED000_KM = 0.06
SEED000_J_KGM2 = 6.88e-4 + 0.001


# Loop set-up for seed 000's controller (not stated in the paper, chosen and documented):
# the incremental PID's gains (Kp 0.15, Ki 0.32, Kd 0.07, per sample as in eq. 11) act on
# encoder volts, i.e. speed / 8.0 (eq. 10: 40 r/min <-> 5 V), at a 0.1 s loop period
# (CAN-bus rate). In r/min the loop gain would be 8x larger and Ki = 0.32 per sample
# unstable at any period; at 1-20 ms periods the loop is too fast for the printed gains.
SEED000_LOOP_PERIOD_S = 0.1
SEED000_FEEDBACK_SCALE = 1.0 / SEED000_FEEDBACK


def seed000_motor_den(time_constant: str = "printed") -> tuple[float, float, float]:
    """Motor denominator T_d T_m s^2 + T_m' s + 1 of seed 000 eq. 7-8.

    ``printed``: eq. 8 as printed, 0.00032 s^2 + 0.16 s + 1.
    ``derived``: from the printed motor data, T_d = L_a / R_m = 1.24 ms and
    T_m = (J_m + J_L) R_m / (C_e K_m) = 0.270 s (eq. 5-6), i.e.
    (T_d s + 1)(T_m s + 1) = 0.000335 s^2 + 0.2717 s + 1. The paper's 0.16 s
    does not follow from its own data (docs/science.md).
    """
    if time_constant == "printed":
        return (0.00032, 0.16, 1.0)
    if time_constant == "derived":
        td = SEED000_LA_H / SEED000_RM_OHM
        tm = SEED000_J_KGM2 * SEED000_RM_OHM / (SEED000_CE * SEED000_KM)
        return (td * tm, td + tm, 1.0)
    raise ValueError("time_constant must be 'printed' or 'derived'")


def seed000_shaft(
    dt: float,
    *,
    time_constant: str = "printed",
    u_min: float = 0.0,
    u_max: float = 5.0,
) -> DiscretePlant:
    """Seed 000 chain: command [V] -> measured shaft speed [r/min].

    Chain (eq. 3, 8, 9, 10): driver 2.4 e^(-0.01 s), motor 19.2 / (...),
    reducer 0.028, encoder 8.0. The paper does not say how the blocks are
    joined; we put all four in the forward path, so the loop compares the
    setpoint in r/min with the encoder reading and the static gain is
    2.4 * 19.2 * 0.028 * 8.0 = 10.3 r/min per volt (40 r/min needs 3.9 V,
    consistent with eq. 10's "40 r/min at 5 V under load"). The actuator is
    the driver's 0-5 V analogue speed input, hence the default limits. ``dt``
    must divide the 10 ms dead time.
    """
    gain = SEED000_DRIVER_GAIN * (1.0 / SEED000_CE if time_constant == "derived" else 19.2)
    gain *= SEED000_REDUCER * SEED000_FEEDBACK
    return DiscretePlant.from_tf(
        (gain,),
        seed000_motor_den(time_constant),
        dt,
        u_min=u_min,
        u_max=u_max,
        delay_s=SEED000_DEAD_TIME_S,
        name=f"seed000_shaft_{time_constant}",
    )


# Seed 002 eq. 3-9.
SEED002_KM = 0.1
SEED002_G2 = (26.091, 0.592)
SEED002_REDUCER = 0.1
SEED002_KQ = 10.0
SEED002_ARM_MM = 320.0
SEED002_ROLLER_MM = 140.0
SEED002_CYLINDER_MM_S = 50.0


def seed002_open_loop_gain() -> float:
    """K of G(s) = K / (s (0.592 s + 1)), seed 002 eq. 8: 0.1 * 26.091 * 0.1 * 10."""
    return SEED002_KM * SEED002_G2[0] * SEED002_REDUCER * SEED002_KQ


def seed002_closed_loop_den() -> tuple[float, float, float]:
    """Corrected denominator of seed 002 eq. 9: 0.592 s^2 + s + K / (L + R).

    **Erratum:** the paper prints 1200.186 = K (L + R); with H = 1 / (L + R)
    the constant is K / (L + R) = 0.005672.
    """
    k = seed002_open_loop_gain()
    return (SEED002_G2[1], 1.0, k / (SEED002_ARM_MM + SEED002_ROLLER_MM))


def seed002_depth(
    dt: float,
    *,
    u_limit: float | None = None,
) -> DiscretePlant:
    """Seed 002 corrected closed loop G_Z(s) = 2.6091 / (0.592 s^2 + s + 0.005672).

    This inner loop (adjusting mechanism with the sensor feedback H) is the
    plant of the depth controller, whose outer loop compares target and
    measured depth in mm. Near-integrating: poles at -0.0057 and -1.683 s^-1.
    The actuator limit defaults to the servo cylinder's fixed 50 mm/s stroke
    speed (seed 002 sec. 4.1): |u| <= 50 / 2.6091 = 19.2, since dy/dt -> 2.6091 u.
    """
    lim = SEED002_CYLINDER_MM_S / seed002_open_loop_gain() if u_limit is None else u_limit
    return DiscretePlant.from_tf(
        (seed002_open_loop_gain(),),
        seed002_closed_loop_den(),
        dt,
        u_min=-lim,
        u_max=lim,
        name="seed002_depth",
    )
