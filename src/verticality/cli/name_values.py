"""``NAME=VALUE`` options (``--param``) read into ``{NAME: value}``: the command line's strings
become numbers here, so the library only ever receives values."""

from __future__ import annotations

import math

from verticality.core.errors import InputError


def parse_name_values(items, names, allow_inf: bool = False) -> dict[str, float]:
    """``["NAME=VALUE", ...]`` (the ``--param`` options of a command) → ``{NAME: value}``, each
    NAME one of ``names`` and each VALUE a number: finite, or also ±inf with ``allow_inf`` (an
    infinite time constant, say); never NaN (:class:`verticality.core.errors.InputError`, one line
    each)."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = str(item).partition("=")
        name = name.strip()
        if not sep:
            raise InputError(f"--param {item!r}: expected NAME=VALUE")
        if name not in names:
            raise InputError(f"--param {name}: unknown name; choose from {', '.join(names)}")
        try:
            v = float(value)
        except ValueError:
            raise InputError(f"--param {name}: not a number: {value!r}") from None
        if math.isnan(v):
            raise InputError(f"--param {name}: NaN is not a value")
        if math.isinf(v) and not allow_inf:
            raise InputError(f"--param {name}: {value.strip()} is not finite")
        out[name] = v
    return out
