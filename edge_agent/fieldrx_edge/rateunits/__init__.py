"""Rate units: what a prescription's numbers count (kg/ha, l/ha, ...), one class per unit
in ``rateunits/units/``, listed by ``rateunits.registry``."""
