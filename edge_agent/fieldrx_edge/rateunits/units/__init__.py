"""The registered rate units, one module each (found by ``rateunits.registry``)."""
