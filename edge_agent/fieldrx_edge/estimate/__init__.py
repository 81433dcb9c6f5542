"""Estimators: GNSS speed (Kalman), sliding-window mean, lag compensation."""

from fieldrx_edge.estimate.kalman import KalmanSpeedFilter
from fieldrx_edge.estimate.lag import lag_time_s, look_ahead
from fieldrx_edge.estimate.window import SlidingWindowMean

__all__ = ["KalmanSpeedFilter", "SlidingWindowMean", "lag_time_s", "look_ahead"]
