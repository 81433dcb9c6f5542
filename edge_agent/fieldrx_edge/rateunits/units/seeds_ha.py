"""seeds/ha: a seeding prescription, sent as count per area (DDI 11/12).

The prescription counts seeds that grow: a mass meter (a drill's fluted roller, calibrated
in g per revolution) sows the seed lot by weight, so one seed/ha is
TKW / 1e6 / (germination / 100) kg/ha (TKW: thousand-kernel weight in g; germination in
%: more seed is sown where fewer of them grow). Worked example: 80 000 seeds/ha of a maize
lot with TKW 320 g and 95 % germination = 80 000 x 320 / 1e6 / 0.95 = 26.95 kg/ha.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from fieldrx_edge.rateunits.registry import LotValue, Quantity, RateUnit, register


@register
class SeedsPerHa(RateUnit):
    name: ClassVar[str] = "seeds/ha"
    label: ClassVar[str] = "seeds/ha (count, through the seed lot)"
    quantity: ClassVar[Quantity] = "count"
    order: ClassVar[int] = 20
    lot: ClassVar[tuple[LotValue, ...]] = (
        # from poppy and rape (3-6 g) to broad beans (~2 000 g)
        LotValue("tkw_g", "thousand-kernel weight", "g", 0.1, 3000.0),
        # a lot below 50 % would not be sown; the certificate states it
        LotValue("germination_pct", "germination", "%", 50.0, 100.0),
    )
    seed_lot: ClassVar[bool] = True
    # ISO 11783-11 DDI 11 / 12, 0.001 /m^2: 1 seed/ha = 1e-4 /m^2 = 0.1 of the value
    ddi_setpoint: ClassVar[int] = 11
    ddi_actual: ClassVar[int] = 12
    bits_per_unit: ClassVar[float] = 0.1

    def kg_per_unit(self, lot: Mapping[str, float]) -> float:
        return lot["tkw_g"] / 1e6 / (lot["germination_pct"] / 100.0)
