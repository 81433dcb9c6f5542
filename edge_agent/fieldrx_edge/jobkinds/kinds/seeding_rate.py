"""Variable-rate seeding: a prescription in seeds/ha, metered cell by cell.

The rates are the prescription's, as in seed 001's prescription map, and the agent runs the
same cell pipeline (path-ordered cells, lag compensation, the metering shaft's controller).
What differs is what is metered: seed, in seeds/ha. An ISOBUS seeder that meters a count
per area (DDI 11) takes the rates as they are; a mass meter (a drill's roller calibrated in
g per revolution, or an ISOBUS mass-rate implement) takes them in kg/ha through the seed
lot's thousand-kernel weight and germination, which the job package carries
(``fieldrx_edge.rateunits``' seeds/ha).
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from fieldrx_edge.jobkinds.registry import JobKind, Needs, register


@register
class SeedingRate(JobKind):
    name: ClassVar[str] = "seeding_rate"
    label: ClassVar[str] = "Variable-rate seeding (seeds/ha)"
    noun: ClassVar[str] = "variable-rate seeding"
    source: ClassVar[str] = "prescription in seeds/ha (seed 001's cell pipeline)"
    rates_from: ClassVar[Literal["cells", "sensors"]] = "cells"
    progress: ClassVar[Literal["cells", "work"]] = "cells"
    order: ClassVar[int] = 5
    rate_units: ClassVar[tuple[str, ...]] = ("seeds/ha",)
    defaults: ClassVar[dict[str, Any]] = {}
    needs: ClassVar[Needs] = Needs(
        applies="seed", text="a seeder or drill whose seed meter is calibrated"
    )
    hand_overrides: ClassVar[bool] = True
