"""Seed 001's prescription map: the rates are the prescription's, cell by cell.

No settings: the job package carries the cells' rates, the machine's calibration and its
controller; the agent runs the cell pipeline (``runtime.py``) and the simulator
(``sim/simulator.py``), the registry's default when a kind has no entry points of its own.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from fieldrx_edge.jobkinds.registry import JobKind, Needs, register


@register
class PrescriptionMap(JobKind):
    name: ClassVar[str] = "prescription_map"
    label: ClassVar[str] = "Prescription map (seed 001)"
    noun: ClassVar[str] = "prescription-map"
    source: ClassVar[str] = "seed 001"
    rates_from: ClassVar[Literal["cells", "sensors"]] = "cells"
    progress: ClassVar[Literal["cells", "work"]] = "cells"
    order: ClassVar[int] = 0
    rate_units: ClassVar[tuple[str, ...]] = ("kg/ha", "l/ha")  # fertiliser: solid or liquid
    defaults: ClassVar[dict[str, Any]] = {}
    needs: ClassVar[Needs] = Needs(applies="fertiliser", text="an implement that meters fertiliser")
    hand_overrides: ClassVar[bool] = True
