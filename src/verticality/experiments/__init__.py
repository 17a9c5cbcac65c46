"""Registry of named, reproducible experiments.

An experiment module in this package registers itself with :func:`register`; the registry imports
every module of the package on first use (:func:`discover`), so adding an experiment is adding a
file.

Each experiment returns a :class:`Result`: metrics (the JSON contract of docs/reproduction.md), the
published values (``paper``), time series for figures, and the simulated duration. Figures are drawn
by the experiment's ``figures`` function from the result, so that ``--json`` runs need no plotting.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Result:
    metrics: dict[str, Any]
    paper: dict[str, Any] = field(default_factory=dict)
    series: dict[str, Any] = field(default_factory=dict)
    simulated_s: float = 0.0
    notes: str = ""


@dataclass(frozen=True)
class Experiment:
    name: str
    title: str
    run: Callable[..., Result]  # run(quick: bool = False) -> Result
    figures: Callable[[Result, Path], list[Path]] | None = None
    source: str = ""  # where in the seeds it comes from, e.g. "P13 §5"


_REGISTRY: dict[str, Experiment] = {}
_DISCOVERED = False


def register(name: str, title: str, source: str = "", figures=None):
    """Decorator: register ``run(quick=False) -> Result`` as experiment ``name``."""

    def deco(run):
        if name in _REGISTRY:
            raise ValueError(f"experiment {name!r} registered twice")
        _REGISTRY[name] = Experiment(name=name, title=title, run=run, figures=figures,
                                     source=source)
        return run

    return deco


def discover() -> dict[str, Experiment]:
    """Import every experiment module of this package once; return the registry."""
    global _DISCOVERED
    if not _DISCOVERED:
        for mod in pkgutil.iter_modules(__path__):
            if not mod.name.startswith("_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _DISCOVERED = True
    return dict(_REGISTRY)


def get(name: str) -> Experiment:
    reg = discover()
    if name not in reg:
        from verticality.core.errors import InputError

        known = ", ".join(sorted(reg))
        raise InputError(f"unknown experiment {name!r}; known: {known}")
    return reg[name]


def check(value, tolerance, passed) -> dict[str, Any]:
    """A validation metric: ``{"value": .., "tolerance": .., "pass": ..}`` with plain floats."""
    return {"value": float(value), "tolerance": float(tolerance), "pass": bool(passed)}
