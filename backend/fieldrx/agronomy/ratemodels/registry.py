"""The rate models' registry: the base class every model subclasses and the one list.

Each other module of this package is one rate model (its paper, equation, parameters and
per-cell input) and registers itself with ``@RATE_MODELS.register``; ``rate_models()``
imports them all on first use (pkgutil, as the job kinds' registries do). Everything that
lists models (the API's accepted values and OpenAPI enum, the CLI's choices, the error
messages, the browser's forms through ``registry_json``) reads them from here, so adding
a model is a new module and nothing else.

Pure: numpy and the standard library only, no database, no API.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from fieldrx.registry import Registry

PACKAGE = "fieldrx.agronomy.ratemodels"


class RateModelError(ValueError):
    """Bad model name or parameter; the message names the parameter."""


@dataclass(frozen=True)
class Param:
    """One parameter of a model: its unit, its default (None: the request, the crop or the
    product gives it) and where that default comes from, and the other names it is
    accepted under."""

    name: str
    unit: str
    default: float | None = None
    source: str = ""
    aliases: tuple[str, ...] = ()


@dataclass(frozen=True)
class Input:
    """The per-cell value a model reads: a sample column and how messages name it."""

    column: str  # the soil sample column (``agronomy.soil``) that feeds the model
    label: str  # "soil n_mg_kg": what a message asking for it says


class RateModel:
    """One rate model; subclasses set the attributes and implement ``compute``."""

    name: str = ""
    aliases: tuple[str, ...] = ()  # other names the API accepts (older clients')
    label: str = ""  # the prescription form's menu entry
    short_label: str = ""  # the model in words where a screen names it
    zone_label: str = ""  # the soil-zones form's menu entry (models with an input)
    paper: str = ""  # where the formula comes from
    input: Input | None = None  # None: the same rate everywhere, no per-cell data
    params: tuple[Param, ...] = ()
    # True: the crop's defaults (target yield, e, k, eq. 20's a and b) and the product's
    # N fraction fill the parameters the request leaves out (``services.prescriptions``)
    crop_defaults: bool = False
    # False: the model's rates are kg/ha of product; True: they are in the prescription's
    # rate unit (seeds/ha), turned into kg/ha through the product lot when the
    # prescription is built (``agronomy.prescription.RateRules.model_kg_per_unit``)
    rates_in_unit: ClassVar[bool] = False

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    def default(self, name: str) -> float:
        """The parameter's default; a KeyError (a missing parameter) when it has none."""
        d = self.param(name).default
        if d is None:
            raise KeyError(name)
        return d

    def compute(self, values: np.ndarray, p: dict[str, Any]) -> np.ndarray:
        """Rates from the per-cell ``values``, popping the parameters it reads from ``p``
        (what is left over is an unknown parameter)."""
        raise NotImplementedError

    def compute_uniform(self, p: dict[str, Any], n: int) -> np.ndarray:
        """Rates of a model without an input, popping the parameters it reads from ``p``."""
        raise NotImplementedError

    def take(self, p: dict[str, Any], name: str) -> float:
        """Pop parameter ``name`` from ``p`` as a float, else its default."""
        return float(p.pop(name)) if name in p else self.default(name)

    def curve_kg_ha(self, params: dict[str, Any]) -> tuple[float, float] | None:
        """The end points of a rate curve the map is checked against (plausibility), None
        for a model without one."""
        return None

    def rates(self, values: np.ndarray | None, params: dict[str, Any], n: int) -> np.ndarray:
        """Rates for ``n`` cells from ``values`` (the model's input, NaN = no data, which
        stays NaN for the caller's fallback); RateModelError names a bad parameter."""
        p = dict(params)
        try:
            if self.input is None:
                out = self.compute_uniform(p, n)
                if p:
                    raise RateModelError(f"model {self.name!r}: unknown parameters {sorted(p)}")
                return out
            if values is None:
                raise RateModelError(f"model {self.name!r} needs per-cell values (soil N or NDVI)")
            v = np.asarray(values, dtype=float)
            out = self.compute(v, p)
        except KeyError as exc:
            raise RateModelError(f"model {self.name!r} needs parameter {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, RateModelError):
                raise
            raise RateModelError(f"model {self.name!r}: bad parameter value ({exc})") from None
        if p:
            raise RateModelError(f"model {self.name!r}: unknown parameters {sorted(p)}")
        return np.where(np.isnan(v), np.nan, out)


RATE_MODELS: Registry[RateModel] = Registry("rate model")
_listed: list[Registry[RateModel]] = []

# the model a request without one gets (the API's default, the CLI's)
DEFAULT_MODEL = "nutrient_balance"
# the order the models are listed in (forms, enums, messages): the default model first,
# then as they were listed before they were classes; a new model goes after them, by name.
# Registration order depends on which module some caller imported first, so the list is
# sorted rather than taken as registered: the OpenAPI document must not change with it.
ORDER = (DEFAULT_MODEL, "ndvi", "uniform")


def _rank(m: RateModel) -> tuple[int, str]:
    return (ORDER.index(m.name) if m.name in ORDER else len(ORDER), m.name)


def rate_models() -> Registry[RateModel]:
    """Every model of this package (each module imported, so registered), in ``ORDER``."""
    if not _listed:
        package = importlib.import_module(PACKAGE)
        for info in pkgutil.iter_modules(package.__path__):
            if info.name != "registry":
                importlib.import_module(f"{PACKAGE}.{info.name}")
        listed: Registry[RateModel] = Registry(RATE_MODELS.what)
        for m in sorted(RATE_MODELS, key=_rank):
            listed.add(m)
        _listed.append(listed)
    return _listed[0]


def names(where: Callable[[RateModel], bool] | None = None) -> tuple[str, ...]:
    return rate_models().names(where)


def rate_model(name: str) -> RateModel:
    """The model named ``name`` (not an alias); RateModelError naming the known ones."""
    reg = rate_models()
    if name not in reg:
        raise RateModelError(f"unknown model {name!r} (expected one of {list(reg.names())})")
    return reg.get(name)


def find_model(name: str) -> RateModel | None:
    """The model named ``name`` or one of its aliases; None when there is none."""
    for m in rate_models():
        if name == m.name or name in m.aliases:
            return m
    return None


def needs_input(name: str) -> bool:
    """Whether model ``name`` reads per-cell values; an unknown name counts as one that
    does, so it is refused by the rates (naming the known models) rather than skipped."""
    reg = rate_models()
    return name not in reg or reg.get(name).input is not None


def model_aliases() -> dict[str, str]:
    """Alias -> model name, over every model."""
    return {a: m.name for m in rate_models() for a in m.aliases}


def param_aliases() -> dict[str, str]:
    """Alias -> parameter name, over every model: an alias names the same parameter
    whichever model the request asks for (a wrong one is then an unknown parameter)."""
    return {a: p.name for m in rate_models() for p in m.params for a in p.aliases}


def accepted_names() -> list[str]:
    """What a request's ``model`` may be: every model's name, then every alias."""
    reg = rate_models()
    return [*reg.names(), *(a for m in reg for a in m.aliases)]


def registry_json() -> str:
    """The registry as the browser reads it (``scripts/gen-api.sh`` writes it)."""
    items = [
        {
            "name": m.name,
            "aliases": list(m.aliases),
            "label": m.label,
            "short_label": m.short_label,
            "zone_label": m.zone_label,
            "paper": m.paper,
            "input": None if m.input is None else m.input.column,
            "crop_defaults": m.crop_defaults,
            "rates_in_unit": m.rates_in_unit,
            "params": [
                {"name": p.name, "unit": p.unit, "default": p.default, "source": p.source}
                for p in m.params
            ],
        }
        for m in rate_models()
    ]
    return json.dumps({"rate_models": items}, indent=2) + "\n"
