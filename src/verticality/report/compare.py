"""Ours against the published figures: metric lookup, one verdict per figure, one per experiment.

Verdicts (:data:`STATUSES`): ``better`` (ours beats the published figure, under the seed's own
reading of its setting), ``meets`` (ours is at or within it), ``differs`` (ours is outside it),
``our setting`` (a magnitude measured under our improved setting, shown beside the published one
and not judged: it is another experiment), ``not judged`` (a published figure shown beside ours
whose row says why it is not judged: another measure or another estimator), ``no published
number`` (nothing to judge against),
``not measured`` (the results have no such metric), ``not run`` (the experiment is not in the
results).

What is judged is the seed's *finding* — a ratio, a region, a sign, a bound — each published figure
marked with the setting ours is measured under (:data:`verticality.report.claims.Setting`): a bound,
a ratio or a region is judged under any setting (does the finding hold there too?), an
approximate magnitude only under the seed's reading. An experiment's verdict (:func:`overall`)
rests on its figures under the seed's reading when it has any that are judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from verticality.report.claims import Claim, MetricPath, Published

BETTER, MEETS, DIFFERS, OUR_SETTING = "better", "meets", "differs", "our setting"
NO_NUMBER, NOT_MEASURED, NOT_RUN = "no published number", "not measured", "not run"
NOT_JUDGED = "not judged"
STATUSES = (BETTER, MEETS, DIFFERS, OUR_SETTING, NOT_JUDGED, NO_NUMBER, NOT_MEASURED, NOT_RUN)
JUDGED = (BETTER, MEETS, DIFFERS)
_MISSING = object()


def lookup(metrics: Any, path: MetricPath) -> Any:
    """The value at ``path`` (keys and list indices); a check dict gives its ``value``.
    Returns the module's ``_MISSING`` sentinel (test with :func:`is_missing`) when absent."""
    node = metrics
    for key in path:
        if isinstance(node, dict) and isinstance(key, str) and key in node:
            node = node[key]
        elif isinstance(node, list) and isinstance(key, int) and -len(node) <= key < len(node):
            node = node[key]
        else:
            return _MISSING
    if is_check(node):
        return node["value"]
    return node


def is_missing(value: Any) -> bool:
    return value is _MISSING


def is_check(value: Any) -> bool:
    """A pass/fail check metric ``{"value", "tolerance", "pass"}``."""
    return isinstance(value, dict) and {"value", "pass"} <= set(value)


def checks(metrics: Any, prefix: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], dict]]:
    """Every check dict in ``metrics`` with its key path, in document order."""
    out: list[tuple[tuple[str, ...], dict]] = []
    if isinstance(metrics, dict):
        for key, value in metrics.items():
            if is_check(value):
                out.append(((*prefix, str(key)), value))
            elif isinstance(value, dict):
                out.extend(checks(value, (*prefix, str(key))))
    return out


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _reduce(value: Any, how: str | None) -> Any:
    if how is None or not isinstance(value, list):
        return value
    numbers = [v for v in (_number(x) for x in value) if v is not None]
    if not numbers:
        return None
    return max(numbers) if how == "max" else min(numbers)


def ours(metrics: dict, pub: Published) -> Any:
    """Our value for a published figure: looked up, reduced, divided; missing stays missing."""
    if pub.metric is None:
        return _MISSING
    value = _reduce(lookup(metrics, pub.metric), pub.reduce)
    if pub.ratio_to is None or is_missing(value):
        return value
    denominator = _number(lookup(metrics, pub.ratio_to))
    numerator = _number(value)
    if numerator is None or denominator in (None, 0.0):
        return None
    return numerator / denominator


def _within(value: Any, target: Any, rel: float) -> bool | None:
    if isinstance(target, list):
        if not isinstance(value, list) or len(value) != len(target):
            return None
        parts = [_within(v, t, rel) for v, t in zip(value, target, strict=True)]
        return None if any(p is None for p in parts) else all(parts)
    v, t = _number(value), _number(target)
    if v is None or t is None:
        return None
    return abs(v - t) <= rel * abs(t)


def verdict(value: Any, pub: Published) -> str:
    """The status of ``value`` (ours) against one published figure."""
    if pub.kind == "context" and pub.value is not None:
        return NOT_JUDGED  # a number shown beside ours; its text says why it is not judged
    if pub.kind == "context" or pub.value is None and pub.kind != "equals":
        return NO_NUMBER  # nothing to judge, whether or not this run measured it
    if pub.metric is None or is_missing(value):
        return NOT_MEASURED
    if pub.kind == "equals":
        return MEETS if value == pub.value else DIFFERS
    if pub.kind == "within":
        ok = _within(value, pub.value, pub.rel)
        return DIFFERS if ok is None else (MEETS if ok else DIFFERS)
    v, target = _number(value), float(pub.value)
    if v is None:
        return DIFFERS  # a null where a number is published: diverged or not finite
    if pub.kind == "at_most":
        return MEETS if v <= target else DIFFERS
    if pub.kind == "at_least":
        return MEETS if v >= target else DIFFERS
    if pub.kind == "approx_error":
        if pub.setting != "seed":
            return OUR_SETTING  # a magnitude of another experiment: shown, not judged
        if v < (1.0 - pub.rel) * target:
            return BETTER
        return MEETS if v <= (1.0 + pub.rel) * target else DIFFERS
    raise ValueError(f"unknown comparison kind {pub.kind!r}")


@dataclass(frozen=True)
class Row:
    """One published figure beside ours, judged."""

    published: Published
    ours: Any  # may be the missing sentinel: test with is_missing
    status: str


    @property
    def setting(self) -> str:
        return self.published.setting


def rows(claim: Claim | None, metrics: dict) -> list[Row]:
    if claim is None:
        return []
    out = []
    for pub in claim.published:
        value = ours(metrics, pub)
        out.append(Row(pub, value, verdict(value, pub)))
    return out


def overall(statuses: list[str], ran: bool = True, settings: list[str] | None = None) -> str:
    """One experiment's status from its rows: any ``differs`` wins, then ``better``, ``meets``;
    ``not measured`` when a published figure has no metric; ``our setting`` when only magnitudes
    under our setting are shown; else ``no published number``. With ``settings`` (one per status),
    the rows under the seed's reading decide when any of them is judged (:data:`JUDGED`)."""
    if not ran:
        return NOT_RUN
    if settings is not None:
        seed = [s for s, where in zip(statuses, settings, strict=True) if where == "seed"]
        if any(s in JUDGED for s in seed):
            statuses = seed
    for status in (DIFFERS, BETTER, MEETS, NOT_MEASURED, OUR_SETTING, NOT_JUDGED):
        if status in statuses:
            return status
    return NO_NUMBER


def overall_rows(rows_: list[Row], ran: bool = True) -> str:
    """:func:`overall` of judged rows, the seed's reading deciding."""
    return overall([r.status for r in rows_], ran, [r.setting for r in rows_])
