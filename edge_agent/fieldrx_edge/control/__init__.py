"""Loop controllers behind one interface (``Controller``) and a name-based factory."""

from __future__ import annotations

from typing import Any

from fieldrx_edge.control.base import Controller
from fieldrx_edge.control.fuzzy import FuzzyPID
from fieldrx_edge.control.ladrc import LADRC
from fieldrx_edge.control.pid import PID, IncrementalPID

__all__ = ["PID", "LADRC", "Controller", "FuzzyPID", "IncrementalPID", "make_controller"]

_FACTORY: dict[str, type[Controller]] = {
    "pid": PID,
    "incremental_pid": IncrementalPID,
    "isp": IncrementalPID,
    "ladrc": LADRC,
    "fuzzy_pid": FuzzyPID,
}


def make_controller(name: str, **params: Any) -> Controller:
    """Build a controller from a job package's control settings.

    ``name`` is one of pid, incremental_pid (alias isp), ladrc, fuzzy_pid
    (case-insensitive); ``params`` go to the class constructor.
    """
    key = name.strip().lower()
    try:
        cls = _FACTORY[key]
    except KeyError:
        raise ValueError(f"unknown controller {name!r}; choose one of {sorted(_FACTORY)}") from None
    return cls(**params)
