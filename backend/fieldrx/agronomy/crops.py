"""Crop parameter sets for the nutrient-balance model (seed 001 eq. 19-21), every value with
its source, and the per-nutrient plausibility ceilings a prescription is checked against.

Pure data and arithmetic: no database. The organisation's own ceilings (a regional legal N
limit, say) live in the database and override ``Crop.ceilings_kg_ha`` (``services``).

Where the values come from, and how sure we are of them:

* Oilseed rape: seed 001 itself (e = 5.8 kg N per 100 kg, k = 0.342, eq. 20's soil
  correction d = (5.57 + 3226.05 / n) / 100).
* Nutrient uptake per 100 kg of economic yield (N, P2O5, K2O): the table used by China's
  national soil-testing and formula-fertilisation programme (测土配方施肥, "nutrients needed to
  form 100 kg of economic yield"), reproduced in Chinese soil-fertility textbooks.
* Fertiliser N utilisation: Zhang F. et al. (2008), Acta Pedologica Sinica 45(5): 915-924,
  N recovery efficiency measured in on-farm trials (rice 28.3 %, wheat 28.2 %, maize 26.1 %).
* N ceilings: Germany's fertiliser ordinance (Düngeverordnung 2020, Anlage 4 Tabelle 2,
  N-Bedarfswerte) where it covers the crop.
These were transcribed without the publications at hand: the ``source`` text says so
where a value is an assumption, and every value can be overridden per prescription (and
the ceilings per organisation).

Eq. 20's soil correction was fitted for oilseed rape; no crop-specific regression for the
other crops is at hand, so their eq. 20 slope is *calibrated*: chosen so that the model
gives the crop's published N rate (``Calibration``) at its reference yield on a soil of
100 mg/kg alkali-hydrolysable N. The source of that slope says so; a regional regression
should replace it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fieldrx.agronomy.ratemodels.nutrient_balance import (
    D_INTERCEPT_PCT,
    D_SLOPE_PCT_MG_KG,
    DEFAULT_E_KG_PER_100KG,
    DEFAULT_K_UTILISATION,
    SOIL_KG_HA_PER_MG_KG,
)

SEED_001 = "seed 001 eq. 19-21 (winter oilseed rape, Hubei)"
UPTAKE_TABLE = (
    "China soil-testing formula fertilisation table, nutrients per 100 kg economic yield "
    "(测土配方施肥)"
)
ZHANG_2008 = "Zhang F. et al. 2008, Acta Pedologica Sinica 45(5):915-924, N recovery"
DUEV_2020 = "DüV 2020 Anlage 4 Tab. 2, N-Bedarfswert"
BUILD_UP = (
    "FieldRx assumption: 1.5 x the crop's uptake at the reference yield (no published cap at hand)"
)
CALIBRATED = "calibrated: eq. 20 slope that gives the reference N rate at n = 100 mg/kg"
NUTRIENTS = ("N", "P2O5", "K2O")
N_REF_SOIL_MG_KG = 100.0  # the soil the calibration is made at (seed 001's worked example)


@dataclass(frozen=True)
class Sourced:
    """One default value, its unit and where it comes from."""

    value: float
    unit: str
    source: str

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "unit": self.unit, "source": self.source}


@dataclass(frozen=True)
class Calibration:
    """The published N rate (kg N/ha of fertiliser) the eq. 20 slope is fitted to."""

    n_rate_kg_ha: float
    source: str


@dataclass(frozen=True)
class CropSpec:
    """What a crop table row gives: uptake per 100 kg (N, P2O5, K2O), N utilisation, the
    reference yield, N ceiling and, for crops other than the seed's, the calibration."""

    key: str
    name: str
    uptake: tuple[float, float, float]
    uptake_source: str
    k: float
    k_source: str
    yield_t_ha: float
    yield_source: str
    ceiling_n: float
    ceiling_n_source: str
    calibration: Calibration | None = None


def calibrated_d_slope(
    e: float, yield_t_ha: float, k: float, n_rate_kg_ha: float, intercept: float
) -> float:
    """Eq. 20 slope b (d = (a + b / n) / 100) so that eq. 19 gives ``n_rate_kg_ha`` of N at
    n = 100 mg/kg: N k = e M / 100 - 2.25 d n  =>  d = (e M / 100 - N k) / (2.25 n)."""
    n = N_REF_SOIL_MG_KG
    d = (e * yield_t_ha * 1000.0 / 100.0 - n_rate_kg_ha * k) / (SOIL_KG_HA_PER_MG_KG * n)
    if not 0 < d <= 1:
        raise ValueError(f"calibration needs 0 < d <= 1 at n = {n:g}, got {d:.3f}")
    return round((100.0 * d - intercept) * n, 2)


@dataclass(frozen=True)
class Crop:
    """A crop's defaults, each a ``Sourced`` value; ``to_dict`` is the API's shape."""

    key: str
    name: str
    values: dict[str, Sourced]
    n_reference: Calibration | None

    def value(self, name: str) -> float:
        return self.values[name].value

    @property
    def ceilings_kg_ha(self) -> dict[str, float]:
        return {n: self.value(f"ceiling_{n.lower()}_kg_ha") for n in NUTRIENTS}

    def model_defaults(self) -> dict[str, float]:
        """The nutrient-balance parameters this crop fills in (model parameter names)."""
        return {k: self.value(k) for k in MODEL_PARAMS}

    def to_dict(self) -> dict[str, Any]:
        v = self.values
        return {
            "key": self.key,
            "name": self.name,
            # flat values the form fills in (kept for clients of the earlier shape)
            "e_kg_per_100kg": v["e_kg_per_100kg"].value,
            "k_utilisation": v["k_utilisation"].value,
            "target_yield_t_ha": v["target_yield_t_ha"].value,
            "source": v["e_kg_per_100kg"].source,
            "values": {k: s.to_dict() for k, s in v.items()},
            "ceilings_kg_ha": self.ceilings_kg_ha,
            "n_reference": None
            if self.n_reference is None
            else {
                "n_rate_kg_ha": self.n_reference.n_rate_kg_ha,
                "yield_t_ha": v["target_yield_t_ha"].value,
                "soil_n_mg_kg": N_REF_SOIL_MG_KG,
                "source": self.n_reference.source,
            },
        }


# model parameters a crop fills in (ratemodels.nutrient_balance names)
MODEL_PARAMS = ("e_kg_per_100kg", "k_utilisation", "d_intercept_pct", "d_slope_pct_mg_kg")


def make_crop(spec: CropSpec) -> Crop:
    """A ``Crop`` from a table row: the P2O5 / K2O ceilings and, without the seed's own
    regression, the eq. 20 slope are derived (and say so)."""
    e_n, e_p, e_k = spec.uptake
    up = f"{spec.uptake_source} ({spec.name})"
    m = spec.yield_t_ha * 1000.0
    values = {
        "target_yield_t_ha": Sourced(spec.yield_t_ha, "t/ha", spec.yield_source),
        "e_kg_per_100kg": Sourced(e_n, "kg N / 100 kg yield", up),
        "uptake_p2o5_kg_per_100kg": Sourced(e_p, "kg P2O5 / 100 kg yield", up),
        "uptake_k2o_kg_per_100kg": Sourced(e_k, "kg K2O / 100 kg yield", up),
        "k_utilisation": Sourced(spec.k, "fraction", spec.k_source),
        "d_intercept_pct": Sourced(D_INTERCEPT_PCT, "%", "seed 001 eq. 20"),
    }
    if spec.calibration is None:
        values["d_slope_pct_mg_kg"] = Sourced(D_SLOPE_PCT_MG_KG, "% mg/kg", "seed 001 eq. 20")
    else:
        b = calibrated_d_slope(
            e_n, spec.yield_t_ha, spec.k, spec.calibration.n_rate_kg_ha, D_INTERCEPT_PCT
        )
        values["d_slope_pct_mg_kg"] = Sourced(
            b,
            "% mg/kg",
            f"{CALIBRATED} to {spec.calibration.n_rate_kg_ha:g} kg N/ha at "
            f"{spec.yield_t_ha:g} t/ha ({spec.calibration.source})",
        )
    values["ceiling_n_kg_ha"] = Sourced(spec.ceiling_n, "kg N/ha", spec.ceiling_n_source)
    values["ceiling_p2o5_kg_ha"] = Sourced(round(1.5 * e_p * m / 100.0, 1), "kg P2O5/ha", BUILD_UP)
    values["ceiling_k2o_kg_ha"] = Sourced(round(1.5 * e_k * m / 100.0, 1), "kg K2O/ha", BUILD_UP)
    return Crop(spec.key, spec.name, values, spec.calibration)


_SPECS = (
    CropSpec(
        "winter_rape",
        "Winter oilseed rape",
        (DEFAULT_E_KG_PER_100KG, 2.5, 4.3),
        f"N: {SEED_001}; P2O5, K2O: {UPTAKE_TABLE}",
        DEFAULT_K_UTILISATION,
        SEED_001,
        2.5,
        "seed 001 worked example (M = 2500 kg/ha)",
        200.0,
        f"{DUEV_2020} Winterraps at 40 dt/ha",
    ),
    CropSpec(
        "winter_wheat",
        "Winter wheat",
        (3.0, 1.25, 2.5),
        UPTAKE_TABLE,
        0.282,
        f"{ZHANG_2008}, wheat 28.2 %",
        8.0,
        f"{DUEV_2020} reference yield, Winterweizen A/B 80 dt/ha",
        230.0,
        f"{DUEV_2020} Winterweizen A/B at 80 dt/ha",
        Calibration(190.0, "FieldRx assumption: mid-point of 150-230 kg N/ha, upper end DüV"),
    ),
    CropSpec(
        "winter_barley",
        "Winter barley",
        (2.7, 0.9, 2.2),
        UPTAKE_TABLE,
        0.282,
        f"{ZHANG_2008}: wheat's 28.2 % (no barley figure; closest cereal)",
        7.0,
        f"{DUEV_2020} reference yield, Wintergerste 70 dt/ha",
        180.0,
        f"{DUEV_2020} Wintergerste at 70 dt/ha",
        Calibration(150.0, "FieldRx assumption: 5/6 of the DüV value"),
    ),
    CropSpec(
        "maize",
        "Maize (grain)",
        (2.57, 0.86, 2.14),
        UPTAKE_TABLE,
        0.261,
        f"{ZHANG_2008}, maize 26.1 %",
        9.0,
        f"{DUEV_2020} reference yield, Körnermais 90 dt/ha",
        200.0,
        f"{DUEV_2020} Körnermais at 90 dt/ha",
        Calibration(170.0, "FieldRx assumption: 0.85 x the DüV value"),
    ),
    CropSpec(
        "rice",
        "Rice",
        (2.25, 1.1, 2.7),
        f"{UPTAKE_TABLE}, mid-points of the rice ranges",
        0.283,
        f"{ZHANG_2008}, rice 28.3 %",
        7.5,
        "FieldRx assumption: typical irrigated rice yield",
        210.0,
        "FieldRx assumption: no published legal limit at hand for rice",
        Calibration(150.0, "FieldRx assumption for site-specific N in irrigated rice"),
    ),
)

CROPS: tuple[Crop, ...] = tuple(make_crop(s) for s in _SPECS)


def find_crop(key: str | None) -> Crop | None:
    """The crop by key, or by a field's free-text crop name ("winter wheat", "Winter oilseed
    rape"): case and separators ignored; None when nothing matches."""
    if not key:
        return None
    norm = "".join(ch for ch in key.lower() if ch.isalnum())
    for c in CROPS:
        names = {c.key.replace("_", ""), "".join(ch for ch in c.name.lower() if ch.isalnum())}
        if norm in names:
            return c
    for c in CROPS:  # "wheat" for winter_wheat, "rape" / "oilseed rape" for winter_rape
        tail = c.key.split("_")[-1]
        if norm.endswith(tail) or norm == tail:
            return c
    return None
