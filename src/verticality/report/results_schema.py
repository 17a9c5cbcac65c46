"""The shape of ``results.json`` (docs/reproduction.md), checked before a report is built from it
or a rerun merges into it: a file damaged by hand or by another program is refused in one line
that names the key and what was expected, never shown with a wrong verdict (a check's ``"pass"``
recorded as the string ``"false"`` is not a pass) or ended in a traceback."""

from __future__ import annotations

from typing import Any

from verticality.core.errors import InputError

ENTRY_KEYS = {"metrics": dict, "paper": dict, "runtime": dict, "figures": list}
RUNTIME_KEYS = ("wall_s", "simulated_s")


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean",
            type(None): "null", int: "a number", float: "a number"}.get(type(value),
                                                                        type(value).__name__)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_results(data: Any, source: str) -> dict:
    """``data`` (``results.json`` as loaded from ``source``) if it has the shape of a results
    file, else an :class:`InputError` naming the first key that does not."""
    if not isinstance(data, dict) or not isinstance(data.get("experiments"), dict):
        raise InputError(f"{source} is not a results file of `verticality reproduce` "
                         "(no \"experiments\" object)")
    registry = data.get("registry")
    if registry is not None:
        if not isinstance(registry, dict):
            raise InputError(f"{source}: \"registry\" is {_kind(registry)}; expected an object")
        for name, item in registry.items():
            if not isinstance(item, dict):
                raise InputError(f"{source}: registry.{name} is {_kind(item)}; expected an object")
            for key in ("title", "source"):
                if key in item and not isinstance(item[key], str | None):
                    raise InputError(f"{source}: registry.{name}.{key} is {_kind(item[key])}; "
                                     "expected a string")
    prov = data.get("provenance")
    if prov is not None and not isinstance(prov, dict):
        raise InputError(f"{source}: \"provenance\" is {_kind(prov)}; expected an object")
    for name, entry in data["experiments"].items():
        where = f"experiments.{name}"
        if not isinstance(entry, dict):
            raise InputError(f"{source}: {where} is {_kind(entry)}; expected an object")
        for key, kind in ENTRY_KEYS.items():
            if key in entry and not isinstance(entry[key], kind):
                raise InputError(f"{source}: {where}.{key} is {_kind(entry[key])}; expected "
                                 f"{_kind(kind())}")
        for key in RUNTIME_KEYS:
            value = entry.get("runtime", {}).get(key)
            if value is not None and not _is_number(value):
                raise InputError(f"{source}: {where}.runtime.{key} is {_kind(value)}; expected a "
                                 "number of seconds")
        for i, fig in enumerate(entry.get("figures") or []):
            if not isinstance(fig, str):
                raise InputError(f"{source}: {where}.figures[{i}] is {_kind(fig)}; expected a "
                                 "file name")
        _check_checks(entry.get("metrics", {}), f"{where}.metrics", source)
    return data


def _check_checks(node: Any, where: str, source: str) -> None:
    """Every check ``{"value", "pass", ...}`` under ``node`` has a JSON boolean ``pass``."""
    if isinstance(node, dict):
        if {"value", "pass"} <= set(node) and not isinstance(node["pass"], bool):
            raise InputError(f"{source}: {where}.pass is {_kind(node['pass'])} "
                             f"({node['pass']!r}); expected true or false")
        for key, value in node.items():
            _check_checks(value, f"{where}.{key}", source)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            _check_checks(value, f"{where}[{i}]", source)
