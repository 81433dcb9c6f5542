"""Server hooks of the job kinds, keyed by the kind's name (``fieldrx_edge.jobkinds``).

Each module of this package (other than this one) describes one kind's server side and
calls ``register`` when imported; ``hooks(name)`` imports them all on first use. A kind
without a module gets empty hooks: the generic paths (prescription-map jobs, plain
sensor reports) serve it. Callers ask for a hook and call it when there is one, so no
code outside a kind's module names a kind.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

PACKAGE = "fieldrx.jobkinds"
Report = Callable[[list[dict[str, Any]], dict[str, Any], dict[str, Any]], tuple[float, float]]


@dataclass(frozen=True)
class ServerHooks:
    """What the server does for one kind; None: nothing beyond the generic path."""

    name: str
    # job creation: (given settings, machine) -> (settings to validate, note for the
    # job's history); raises fieldrx_edge's SettingsError naming the setting
    prepare: Callable[[dict[str, Any], Any], tuple[dict[str, Any], str]] | None = None
    # job creation: where the validated settings ask for more than the machine can meter
    # (a dict with a ``message``), None when they do not
    meter_conflict: Callable[[dict[str, Any], Any], dict[str, Any] | None] | None = None
    # the report: (records, settings, report) -> the qualified depth band (lo, hi) for
    # the cells' query; adds the kind's figures to the report in place
    report: Report | None = None
    cell_columns: tuple[str, ...] = ()  # the per-cell columns of the kind's map
    outcome: Callable[[Sequence[Any]], dict[str, Any]] | None = None  # report headline
    # ingest: (cursor, machine, organisation, job, settings, open alerts) -> live messages
    live_alerts: Callable[..., list[dict[str, Any]]] | None = None
    job_end: Callable[[Any, Any], Any] | None = None  # (session, job) when it completes


_HOOKS: dict[str, ServerHooks] = {}
_discovered: list[bool] = []


def register(h: ServerHooks) -> ServerHooks:
    _HOOKS[h.name] = h
    return h


def hooks(name: str) -> ServerHooks:
    """The server hooks of kind ``name`` (empty ones for a kind with no module here)."""
    if not _discovered:
        package = importlib.import_module(PACKAGE)
        for info in pkgutil.iter_modules(package.__path__):
            if info.name != "registry":
                importlib.import_module(f"{PACKAGE}.{info.name}")
        _discovered.append(True)
    return _HOOKS.get(name) or ServerHooks(name)
