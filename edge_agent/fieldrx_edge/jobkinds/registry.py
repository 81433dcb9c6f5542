"""The one list of job kinds: each kind is a class in ``jobkinds/kinds/`` that registers
itself here.

What a kind declares (``JobKind``): its name and label, the paper it comes from, where its
rates come from (``cells``: the prescription's per-cell rates; ``sensors``: decided on the
go), how its progress is counted, its settings (defaults, and one ``SettingSpec`` per form
input with unit and source), the controllers it allows, what the machine needs, what the
cab shows, and the agent's entry points. Everything that lists kinds reads them from here:
the API's validation and OpenAPI enum, ``GET /jobs/kinds`` (and through it the UI's
forms), the database's ``job_kinds`` rows, the job package and the agent's dispatch.
Adding a kind is adding a module to ``jobkinds/kinds/``; no list elsewhere names it.

Standard library only at import time (``protocol`` imports this module); the kinds'
modules are imported on first use, so they may import ``protocol`` themselves.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

# a package or a request that names no kind: packages made before kinds existed are seed
# 001's prescription maps, and their bytes (and checksum) leave the kind out
DEFAULT_KIND = "prescription_map"
KINDS_PACKAGE = "fieldrx_edge.jobkinds.kinds"


@dataclass(frozen=True)
class SettingSpec:
    """One input of a kind's form: the dotted settings path, what the user reads beside it,
    and where its default comes from (the default itself is the kind's ``defaults``)."""

    path: str
    label: str
    unit: str = ""
    source: str = "FieldRx"
    step: float | None = None
    options: tuple[str, ...] = ()


@dataclass(frozen=True)
class Needs:
    """What a machine must have for a kind's job (checked at creation and at send)."""

    applies: Literal["fertiliser", "seed"]
    text: str
    sensors: tuple[str, ...] = ()
    depth_actuator: bool = False


class JobKind:
    """A job kind; subclasses set the class attributes and override the hooks they use."""

    name: ClassVar[str]
    label: ClassVar[str]  # for lists and forms
    noun: ClassVar[str]  # in sentences and job names: "a {noun} job"
    source: ClassVar[str]
    rates_from: ClassVar[Literal["cells", "sensors"]]
    # "cells": progress is the share of cells applied; "work": of cells worked (a sensor
    # kind's cells have no prescribed rate to reach)
    progress: ClassVar[Literal["cells", "work"]] = "cells"
    order: ClassVar[int] = 100  # place in lists (forms, the API's enum)
    defaults: ClassVar[dict[str, Any]] = {}
    # a cells kind: the prescription rate units (fieldrx_edge.rateunits) its job takes
    rate_units: ClassVar[tuple[str, ...]] = ()
    controllers: ClassVar[tuple[str, ...]] = ()
    specs: ClassVar[tuple[SettingSpec, ...]] = ()
    needs: ClassVar[Needs]
    # the cab: does the operator see a rate, may they override it by hand
    shows_rate: ClassVar[bool] = True
    hand_overrides: ClassVar[bool] = False
    cab_panel: ClassVar[str] = ""  # the cab's figures of the kind: "", "ndvi" or "depth"

    def check(self, settings: dict[str, Any]) -> None:
        """Check (and normalise) the kind's merged settings in place; ``SettingsError``."""

    def controller_defaults(self, name: str) -> dict[str, Any]:
        """The ``controller`` block of a non-default controller named without params."""
        return {"params": {}}

    def run(self, a: argparse.Namespace, job: Any, store: Any) -> int | None:
        """``fieldrx-edge run`` of this kind's job; None: the cell pipeline (runtime.py)."""
        return None

    def simulate(self, a: argparse.Namespace, job: Any) -> int | None:
        """``fieldrx-edge simulate`` of this kind's job; None: the cell simulator."""
        return None

    def cab_view(self) -> dict[str, Any]:
        """What the cab's page needs to know of the kind (it names no kind itself)."""
        return {
            "rates_from": self.rates_from,
            "shows_rate": self.shows_rate,
            "hand_overrides": self.hand_overrides,
            "panel": self.cab_panel,
        }

    def default_of(self, path: str) -> Any:
        obj: Any = self.defaults
        for part in path.split("."):
            obj = obj[part]
        return obj

    def describe(self) -> dict[str, Any]:
        """The kind as ``GET /jobs/kinds`` and the UI see it."""
        return {
            "name": self.name,
            "label": self.label,
            "noun": self.noun,
            "source": self.source,
            "rates_from": self.rates_from,
            "rate_units": list(self.rate_units),
            "progress": self.progress,
            "defaults": self.defaults,
            "controllers": list(self.controllers),
            "needs": self.needs.text,
            "settings": [
                {
                    "path": s.path,
                    "label": s.label,
                    "unit": s.unit,
                    "default": self.default_of(s.path),
                    "source": s.source,
                    "step": s.step,
                    "options": list(s.options),
                }
                for s in self.specs
            ],
        }


class UnknownKind(ValueError):
    pass


_KINDS: dict[str, JobKind] = {}
_discovered: list[bool] = []


def register(cls: type[JobKind]) -> type[JobKind]:
    """Class decorator: the kind's one registration."""
    if cls.name in _KINDS and type(_KINDS[cls.name]) is not cls:
        raise ValueError(f"job kind {cls.name!r} registered twice")
    _KINDS[cls.name] = cls()
    return cls


def _discover() -> None:
    if _discovered:
        return
    package = importlib.import_module(KINDS_PACKAGE)
    for info in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"{KINDS_PACKAGE}.{info.name}")
    _discovered.append(True)


def kinds() -> list[JobKind]:
    """Every registered kind, in list order."""
    _discover()
    return sorted(_KINDS.values(), key=lambda k: (k.order, k.name))


def names() -> tuple[str, ...]:
    return tuple(k.name for k in kinds())


def kind_of(name: str) -> JobKind:
    """The kind called ``name``; ``UnknownKind`` names the known ones."""
    _discover()
    try:
        return _KINDS[name]
    except KeyError:
        raise UnknownKind(f"unknown job kind {name!r} (known: {list(names())})") from None
