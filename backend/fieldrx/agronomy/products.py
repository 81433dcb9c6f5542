"""Fertiliser products the prescription forms start from, each value named by its source
(crops: ``agronomy.crops``), and the whole-field product / nutrient / cost figures of a rate map.

Pure: the organisation's own products live in the database (``services.products``);
this module holds the defaults every organisation sees and the arithmetic.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from fieldrx.agronomy.crops import SEED_001

ANALYSIS = "nominal analysis of the product"


@dataclass(frozen=True)
class Product:
    """A fertiliser: nutrient mass fractions in % (N, P2O5, K2O) and a price per tonne
    (None: not known, so no cost is shown rather than a guessed one)."""

    key: str
    name: str
    n_pct: float
    p2o5_pct: float = 0.0
    k2o_pct: float = 0.0
    price_per_t: float | None = None
    source: str = ANALYSIS
    id: int | None = None
    density_kg_l: float | None = None  # liquids only: kg/l, for volume-rate implements

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


DEFAULT_PRODUCTS: tuple[Product, ...] = (
    # x = 0.25 is the product of seed 001's worked example (M 2500, n 100 -> 700 kg/ha)
    Product("default:compound_25n", "Compound 25 % N (seed 001 example)", 25.0, source=SEED_001),
    Product("default:urea", "Urea 46-0-0", 46.0),
    Product("default:can", "Calcium ammonium nitrate 27-0-0", 27.0),
    Product("default:an", "Ammonium nitrate 34-0-0", 34.0),
    Product("default:dap", "Diammonium phosphate 18-46-0", 18.0, 46.0),
    Product("default:npk15", "NPK 15-15-15", 15.0, 15.0, 15.0),
    # a liquid: UAN-28 weighs 10.66 lb per US gallon = 1.28 kg/l (nominal, 15 degC)
    Product("default:uan28", "UAN 28-0-0 (liquid)", 28.0, density_kg_l=1.28),
)

NUTRIENTS = (("N", "n_pct"), ("P2O5", "p2o5_pct"), ("K2O", "k2o_pct"))


def product_figures(
    rate_kg_ha: np.ndarray, area_m2: np.ndarray, product: dict[str, Any] | None
) -> dict[str, Any]:
    """Whole-field product, nutrient and cost figures of a rate map.

    product_kg = sum(rate * area_m2) / 10 000; nutrient kg = product_kg * pct / 100 and
    kg/ha = that / area_ha (the area-weighted mean rate times the fraction); cost =
    product_kg / 1000 * price_per_t (None without a price). A product that states no
    nutrient at all (a seed lot) gets no nutrient figures rather than zeros.
    """
    r = np.asarray(rate_kg_ha, dtype=float)
    a = np.asarray(area_m2, dtype=float)
    area_ha = float(a.sum()) / 1e4
    kg = float((r * a).sum()) / 1e4
    out: dict[str, Any] = {"product_t": round(kg / 1000.0, 6)}
    if product is None:
        return out
    price = product.get("price_per_t")
    if not any(col in product for _, col in NUTRIENTS):  # a seed lot: no nutrient figures
        out["cost"] = None if price is None else round(kg / 1000.0 * float(price), 2)
        return out
    nut_kg = {n: kg * float(product.get(col) or 0.0) / 100.0 for n, col in NUTRIENTS}
    out["nutrients_kg"] = {n: round(v, 3) for n, v in nut_kg.items()}
    out["nutrients_kg_ha"] = {
        n: round(v / area_ha, 3) if area_ha > 0 else 0.0 for n, v in nut_kg.items()
    }
    out["cost"] = None if price is None else round(kg / 1000.0 * float(price), 2)
    return out
