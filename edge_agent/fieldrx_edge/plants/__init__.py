"""Simulated plants (the papers' transfer functions) and the motor interface."""

from fieldrx_edge.plants.lti import DiscretePlant
from fieldrx_edge.plants.motor import (
    MotorDriver,
    MotorDriverError,
    SerialMotorDriver,
    SimulatedMotor,
)
from fieldrx_edge.plants.seeds import seed000_shaft, seed001_motor, seed002_depth

__all__ = [
    "DiscretePlant",
    "MotorDriver",
    "MotorDriverError",
    "SerialMotorDriver",
    "SimulatedMotor",
    "seed000_shaft",
    "seed001_motor",
    "seed002_depth",
]
