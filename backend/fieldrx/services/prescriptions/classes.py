"""A version's legend classes: equal classes for a new map, the base version's breaks
kept through an edit, or breaks the user set.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fieldrx.agronomy.prescription import class_breaks, class_table


def legend_classes(
    rates: np.ndarray, area: np.ndarray, breaks: list[float], source: str
) -> dict[str, Any]:
    """A version's legend classes and zones table (class -> ha -> t)."""
    return {"breaks_kg_ha": breaks, "source": source, "table": class_table(rates, area, breaks)}


def auto_classes(rates: np.ndarray, area: np.ndarray, n: int) -> dict[str, Any]:
    lo, hi = (float(rates.min()), float(rates.max())) if len(rates) else (0.0, 1.0)
    # a uniform rate has one class, whatever count was asked
    src = f"{n} equal classes" if hi > lo else "uniform rate: one class"
    return legend_classes(rates, area, class_breaks(lo, hi, n), src)


# said once in a class source, however many edits reach beyond the breaks
_EDITED_CLASS_NOTE = "; edited rates beyond them have a class of their own"


def inherited_classes(
    rates: np.ndarray, area: np.ndarray, base: dict[str, Any] | None
) -> dict[str, Any]:
    """An edit keeps its base version's breaks (the legend does not jump between
    versions). Rates beyond them get a class of their own at that end: widening the
    outer class instead put an edited zone in the colour of the unedited cells (a
    uniform 300 kg/ha map painted at 650 had one class, 300-650, for both)."""
    if not base or not base.get("breaks_kg_ha"):
        return auto_classes(rates, area, 6)
    b = [float(x) for x in base["breaks_kg_ha"]]
    src = str(base.get("source", "")).replace(_EDITED_CLASS_NOTE, "")
    if len(rates):
        lo, hi = float(rates.min()), float(rates.max())
        if lo < b[0]:
            b.insert(0, min(round(lo, 3), b[0] - 1e-3))
        if hi > b[-1]:
            top = b[-1]
            # the last class holds its upper edge: rates on it stay in their class
            if bool((rates == top).any()):
                b[-1] = round(top + 1e-3, 3)
            b.append(max(round(hi, 3), b[-1] + 1e-3))
    if len(b) > len(base["breaks_kg_ha"]) or _EDITED_CLASS_NOTE in str(base.get("source", "")):
        src += _EDITED_CLASS_NOTE
    return legend_classes(rates, area, b, src)
