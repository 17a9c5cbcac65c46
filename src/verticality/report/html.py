"""The report as one self-contained HTML page: inline style, figures embedded as data URIs, no
script and no network. Every text from the results is escaped."""

from __future__ import annotations

import base64
import math
from html import escape
from pathlib import Path
from typing import Any, NamedTuple

from verticality.report import compare
from verticality.report.claims import (
    CLAIMS,
    DIFFERENCES,
    PENDING,
    SETTING_TEXT,
    Claim,
    Difference,
    Evidence,
)

#: Reading order of the experiments: T, then the thesis and the papers; others follow by name.
ORDER = ("tahboub-gains", "tahboub-step", "tahboub-sine", "tahboub-prts", "ground-kf",
         "ground-edo", "model-checks", "observability", "separation", "platform", "ekf-impact",
         "ekf-jump", "ekf-sensitivity", "newton-lissajous", "newton-uncertainty")

_MIME = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}

_STYLE = """
:root { --fg: #1d2327; --muted: #5b6770; --line: #d5dade; --bg-alt: #f5f7f8; }
* { box-sizing: border-box; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
       color: var(--fg); margin: 0; background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 1.5rem 2rem 4rem; }
h1 { font-size: 1.75rem; margin: 0.2rem 0 0.4rem; }
h2 { font-size: 1.35rem; margin: 2.6rem 0 0.6rem; padding-top: 0.6rem;
     border-top: 2px solid var(--line); }
h3 { font-size: 1.08rem; margin: 1.6rem 0 0.4rem; }
nav.top { position: sticky; top: 0; background: #fff; border-bottom: 1px solid var(--line);
          padding: 0.45rem 2rem; font-size: 0.92rem; z-index: 2; }
nav.top a { margin-right: 1.1rem; }
a { color: #0b5cad; text-decoration: none; } a:hover { text-decoration: underline; }
p.meta, .muted { color: var(--muted); }
table { border-collapse: collapse; width: 100%; margin: 0.6rem 0 1rem; font-size: 0.92rem; }
th, td { border: 1px solid var(--line); padding: 0.32rem 0.5rem; text-align: left;
         vertical-align: top; }
th { background: var(--bg-alt); font-weight: 600; }
td.num, td.ours { font-variant-numeric: tabular-nums; }
td.ours { font-weight: 600; } .nowrap { white-space: nowrap; }
table.summary tr.first td { border-top: 2px solid #aab4bb; }
td.wrap { word-break: break-word; }
tr:nth-child(even) td { background: #fbfcfc; }
table.summary tr td { background: #fff; }
.status { display: inline-block; padding: 0.05rem 0.5rem; border-radius: 0.8rem;
          font-size: 0.82rem; font-weight: 600; white-space: nowrap; }
.s-better { background: #cdeccd; color: #14521b; }
.s-meets { background: #e1f2e1; color: #1f5d26; }
.s-differs { background: #fde2c8; color: #8a3b00; }
.s-our-setting { background: #e3ecf8; color: #1b3f6b; }
.s-no-published-number, .s-not-judged { background: #eceff1; color: #455a64; }
.setting { font-size: 0.8rem; color: var(--muted); white-space: nowrap; }
.setting-ours, .setting-alt { color: #1b3f6b; font-weight: 600; }
.s-not-measured { background: #fff3c4; color: #6b5500; }
.s-not-run { background: #eceff1; color: #78848c; }
.pass { color: #1f5d26; font-weight: 600; } .fail { color: #a4000f; font-weight: 700; }
figure { margin: 1rem 0 1.4rem; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); display: block; }
figcaption { color: var(--muted); font-size: 0.85rem; margin-top: 0.25rem; }
.missing { border: 2px dashed #c62828; color: #a4000f; padding: 1rem; }
details { margin: 0.6rem 0 1rem; } summary { cursor: pointer; color: #0b5cad; }
ul { margin: 0.2rem 0 0.8rem 1.2rem; padding: 0; }
.callout { background: #fff8e1; border-left: 4px solid #f0b400; padding: 0.5rem 0.9rem;
           margin: 0.8rem 0; }
.claim { font-size: 1.02rem; }
code { font-size: 0.9em; background: var(--bg-alt); padding: 0 0.2rem; border-radius: 3px; }
@media print { nav.top { position: static; } h2 { break-before: page; } }
"""


# ---------------------------------------------------------------------------------------------
# values


def fmt(value: Any, unit: str = "") -> str:
    """A value as a person reads it (plain text, not escaped)."""
    if compare.is_missing(value):
        return "not measured"
    if compare.is_check(value):
        return fmt(value["value"], unit)
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value}{unit}"
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        if value == 0.0 or 1e-3 <= abs(value) < 1e4:
            text = f"{value:.4g}"
        else:
            text = f"{value:.3g}"
        return f"{text}{unit}"
    if isinstance(value, list):
        if any(isinstance(x, dict) for x in value):
            return f"{len(value)} rows"
        shown = ", ".join(fmt(x) for x in value[:8])
        more = f", … ({len(value)} values)" if len(value) > 8 else ""
        return f"[{shown}{more}]" + (unit if unit and not isinstance(value[0], list) else "")
    text = str(value)
    return text if len(text) <= 240 else text[:237] + "…"


def _slug(status: str) -> str:
    return status.replace(" ", "-")


def badge(status: str) -> str:
    return f'<span class="status s-{_slug(status)}">{escape(status)}</span>'


def anchor(name: str) -> str:
    return "exp-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in name)


def setting_marker(row: compare.Row) -> str:
    """The setting ours is measured under, as a small marker: seed's reading / ours / another
    reading."""
    return (f'<span class="setting setting-{row.setting}">'
            f'{escape(SETTING_TEXT.get(row.setting, row.setting))}</span>')


def _ours_text(row: compare.Row) -> str:
    pub = row.published
    if row.ours is None and pub.none_text != "—":
        return pub.none_text
    if pub.ratio_to is not None and not compare.is_missing(row.ours):
        return f"ratio {fmt(row.ours)}"
    return fmt(row.ours, pub.unit)


# ---------------------------------------------------------------------------------------------
# figures


MAX_FIGURE_BYTES = 32 * 2**20  # a figure larger than this is not embedded (ours: < 1 MiB)


class Figure(NamedTuple):
    """A figure of an experiment: the file (as recorded, when it is not shown) and why it is not
    shown (None: it is embedded)."""

    path: Path
    problem: str | None = None


def figure_paths(name: str, entry: dict, results_dir: Path) -> list[Figure]:
    """The experiment's figures, read from inside ``results_dir`` only: each recorded path looked
    up first beside ``results.json`` (``DIR/NAME/file``, so a moved folder still works), then as
    recorded when that is inside the folder; without a record, the images in ``DIR/NAME/``. A
    file outside the folder, links followed (an absolute path elsewhere, a ``..`` path, an
    experiment named ``../x``, a link planted in the folder) is never read: it is listed with its
    problem, as is a missing file, one that is not a regular file and one too large to embed."""
    from verticality.io.paths import inside, is_plain_name

    plain = is_plain_name(name)
    recorded = entry.get("figures")
    if not recorded:
        folder = results_dir / name
        if not plain or not folder.is_dir():
            return []
        return [_checked(p, results_dir) for p in sorted(folder.glob("*"))
                if p.suffix.lower() in _MIME]
    out = []
    for text in recorded:
        p = Path(str(text))
        candidates = []
        if plain and is_plain_name(p.name):
            candidates.append(results_dir / name / p.name)
        candidates += [p, results_dir / p]  # as recorded: used only when inside the folder
        found = [c for c in candidates if c.is_file() and inside(c, results_dir)]
        if found:
            out.append(_checked(found[0], results_dir))
        elif any(c.exists() or c.is_symlink() for c in candidates):
            out.append(Figure(p, "outside the results folder, not read"))
        elif not plain:
            out.append(Figure(p, f"the experiment's name {name!r} is not a folder name, so its "
                                 "figures are not looked up"))
        else:
            out.append(Figure(p, "missing"))
    return out


def _checked(path: Path, results_dir: Path) -> Figure:
    """``path`` (under ``results_dir``) as a figure to embed, or with the reason it is not."""
    from verticality.io.paths import inside

    if not inside(path, results_dir):
        return Figure(path, "outside the results folder, not read")
    if not path.is_file():
        return Figure(path, "missing" if not path.exists() else "not a regular file")
    size = path.stat().st_size
    if size > MAX_FIGURE_BYTES:
        return Figure(path, f"{size / 2**20:.0f} MiB, larger than the {MAX_FIGURE_BYTES // 2**20}"
                            " MiB a figure may be")
    return Figure(path)


def figure_problems(results: dict, results_dir: Path) -> list[str]:
    """One line per figure of ``results`` that the page does not show because it lies outside
    ``results_dir``, is not a regular file or is too large (missing figures are not listed: the
    page names them)."""
    lines = []
    for name, entry in (results.get("experiments") or {}).items():
        if not isinstance(entry, dict):
            continue
        for fig in figure_paths(str(name), entry, Path(results_dir)):
            if fig.problem is not None and fig.problem != "missing":
                lines.append(f"{name}: figure {fig.path}: {fig.problem}")
    return lines


def figure_html(fig: Figure, name: str) -> str:
    path = fig.path
    mime = _MIME.get(path.suffix.lower())
    problem = fig.problem or (None if mime is not None else "not an image format")
    if problem is None:
        try:
            data = base64.b64encode(path.read_bytes()).decode("ascii")
        except OSError as exc:
            problem = f"cannot be read ({exc.strerror})"
    if problem == "missing":
        return (f'<div class="missing">figure missing: {escape(str(path))} (rerun '
                f'<code>verticality reproduce {escape(name)}</code>)</div>')
    if problem is not None:
        return (f'<div class="missing">figure not shown: {escape(str(path))}: '
                f'{escape(problem)}</div>')
    alt = f"{name}: {path.stem.replace('_', ' ')}"
    return (f'<figure><img src="data:{mime};base64,{data}" alt="{escape(alt)}" '
            f'loading="eager"><figcaption>{escape(path.name)}</figcaption></figure>')


# ---------------------------------------------------------------------------------------------
# sections


def ordered_names(registry: dict, experiments: dict) -> list[str]:
    names = set(registry) | set(experiments)
    first = [n for n in ORDER if n in names]
    return first + sorted(names - set(first))


def _source(name: str, registry: dict) -> str:
    claim = CLAIMS.get(name)
    if claim is not None:
        return claim.source
    return str(registry.get(name, {}).get("source") or "—")


def _check_summary(metrics: dict) -> tuple[int, int]:
    found = compare.checks(metrics)
    return sum(bool(c.get("pass")) for _, c in found), len(found)


def summary_row(name: str, registry: dict, experiments: dict) -> tuple[str, str]:
    """(HTML rows, status) of one experiment in the summary table: one row per headline
    figure, published beside ours, the experiment's cells spanning them."""
    entry = experiments.get(name)
    claim = CLAIMS.get(name)
    title = registry.get(name, {}).get("title", "")
    link = f'<a href="#{anchor(name)}">{escape(name)}</a><div class="muted">{escape(title)}</div>'
    source = escape(_source(name, registry))
    if entry is None:
        status = compare.NOT_RUN
        return (f"<tr class=first><td>{link}</td><td>{source}</td>"
                "<td colspan='3'>not in this results "
                f"folder</td><td>{badge(status)}</td><td>—</td></tr>", status)
    metrics = entry.get("metrics", {})
    rows = compare.rows(claim, metrics)
    status = compare.overall_rows(rows)
    head = [r for r in rows if r.published.headline] or rows[:1]
    passed, total = _check_summary(metrics)
    checks = f"{passed} of {total} pass" if total else "—"
    checks_cls = " fail" if passed < total else ""
    cells = [(escape(r.published.label), escape(r.published.text),
              f"{escape(_ours_text(r))} {setting_marker(r)}") for r in head] or [
        ("—", "no published number", "—")]
    span = f" rowspan='{len(cells)}'" if len(cells) > 1 else ""
    out = []
    for i, (what, published, ours) in enumerate(cells):
        lead = (f"<td{span}>{link}</td><td{span}>{source}</td>" if i == 0 else "")
        tail = (f"<td{span}>{badge(status)}</td><td class='nowrap{checks_cls}'{span}>{checks}"
                "</td>" if i == 0 else "")
        out.append(f"<tr{' class=first' if i == 0 else ''}>{lead}<td>{what}</td>"
                   f"<td>{published}</td><td class='ours'>{ours}</td>"
                   f"{tail}</tr>")
    return "".join(out), status


def _list(title: str, items: tuple[str, ...]) -> str:
    if not items:
        return ""
    lis = "".join(f"<li>{escape(i)}</li>" for i in items)
    return f"<p><strong>{escape(title)}</strong></p><ul>{lis}</ul>"


def comparison_table(rows: list[compare.Row]) -> str:
    if not rows:
        return "<p class='muted'>No published number for this experiment.</p>"
    body = "".join(
        f"<tr><td>{escape(r.published.label)}</td><td>{escape(r.published.source)}</td>"
        f"<td>{escape(r.published.text)}</td><td class='num'>{escape(_ours_text(r))}</td>"
        f"<td>{setting_marker(r)}</td><td>{badge(r.status)}</td></tr>" for r in rows)
    return ("<table><thead><tr><th>what</th><th>where</th><th>published</th><th>ours</th>"
            f"<th>setting</th><th>status</th></tr></thead><tbody>{body}</tbody></table>")


def checks_table(metrics: dict) -> str:
    found = compare.checks(metrics)
    if not found:
        return ""
    body = "".join(
        f"<tr><td><code>{escape('.'.join(path))}</code></td><td class='num'>"
        f"{escape(fmt(c.get('value')))}</td><td class='num'>{escape(fmt(c.get('tolerance')))}"
        f"</td><td class='{'pass' if c.get('pass') else 'fail'}'>"
        f"{'pass' if c.get('pass') else 'FAIL'}</td></tr>" for path, c in found)
    return ("<h3>Checks</h3><table><thead><tr><th>check</th><th>value</th><th>tolerance</th>"
            f"<th>result</th></tr></thead><tbody>{body}</tbody></table>")


def _flat(d: Any, prefix: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], Any]]:
    out: list[tuple[tuple[str, ...], Any]] = []
    if isinstance(d, dict) and not compare.is_check(d):
        for k, v in d.items():
            if isinstance(v, dict) and not compare.is_check(v):
                out.extend(_flat(v, (*prefix, str(k))))
            else:
                out.append(((*prefix, str(k)), v))
    return out


def _rows_table(rows: list[dict]) -> str:
    cols = [k for k in rows[0] if all(not isinstance(r.get(k), list | dict) for r in rows)]
    head = "".join(f"<th>{escape(c)}</th>" for c in cols)
    body = "".join("<tr>" + "".join(f"<td class='wrap'>{escape(fmt(r.get(c)))}</td>"
                                    for c in cols) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def all_metrics(metrics: dict, paper: dict) -> str:
    flat = _flat(metrics)
    published = dict(_flat(paper))
    body = []
    tables = []
    for path, value in flat:
        key = ".".join(path)
        if isinstance(value, list) and value and all(isinstance(r, dict) for r in value):
            tables.append(f"<h4><code>{escape(key)}</code></h4>{_rows_table(value)}")
            continue
        pub = published.get(path, "")
        body.append(f"<tr><td><code>{escape(key)}</code></td><td class='wrap'>"
                    f"{escape(fmt(value))}</td><td class='wrap'>"
                    f"{escape(fmt(pub)) if pub != '' else ''}</td></tr>")
    table = ("<table><thead><tr><th>metric</th><th>ours</th><th>published (as the experiment "
             f"records it)</th></tr></thead><tbody>{''.join(body)}</tbody></table>")
    return (f"<details><summary>All metrics of results.json ({len(flat)})</summary>{table}"
            f"{''.join(tables)}</details>")


def experiment_section(name: str, registry: dict, experiments: dict, results_dir: Path) -> str:
    entry = experiments.get(name)
    claim: Claim | None = CLAIMS.get(name)
    title = registry.get(name, {}).get("title", "")
    parts = [f'<section id="{anchor(name)}"><h2>{escape(name)}'
             f'{" — " + escape(title) if title else ""}</h2>',
             f"<p class='meta'>Tests: {escape(_source(name, registry))}</p>"]
    if entry is None:
        parts.append(f"<p>{badge(compare.NOT_RUN)} Not in this results folder: run "
                     f"<code>verticality reproduce {escape(name)}</code>.</p></section>")
        return "".join(parts)
    metrics, paper = entry.get("metrics", {}), entry.get("paper", {})
    rows = compare.rows(claim, metrics)
    runtime = entry.get("runtime", {})
    parts.append(f"<p>{badge(compare.overall_rows(rows))} "
                 f"<span class='muted'>runtime {escape(fmt(runtime.get('wall_s')))} s wall, "
                 f"{escape(fmt(runtime.get('simulated_s')))} s simulated</span></p>")
    if claim is not None:
        parts.append(f"<p class='claim'>{escape(claim.claim)}</p>")
        parts.append(_list("Settings that matter", claim.settings))
        parts.append(_list("Readings we chose where the seeds are silent", claim.readings))
    else:
        parts.append("<p class='muted'>No seed claim is recorded for this experiment; its "
                     "metrics and figures follow.</p>")
    parts.append("<h3>Ours beside the published figures</h3>")
    parts.append(comparison_table(rows))
    if claim is not None and claim.note:
        parts.append(f"<p class='muted'>{escape(claim.note)}</p>")
    related = [d for d in DIFFERENCES if any(e.experiment == name for e in d.evidence)]
    if related:
        links = ", ".join(f'<a href="#{d.anchor}">{escape(d.title)}</a>' for d in related)
        parts.append(f"<p class='callout'>Where we differ: {links}.</p>")
    parts.append(checks_table(metrics))
    figures = figure_paths(name, entry, results_dir)
    parts.append("<h3>Figures</h3>")
    parts.append("".join(figure_html(p, name) for p in figures)
                 or "<p class='muted'>This experiment draws no figure.</p>")
    parts.append(all_metrics(metrics, paper))
    if claim is not None and claim.pages:
        pages = ", ".join(f"<code>docs/{escape(p)}</code>" for p in claim.pages)
        parts.append(f"<p class='muted'>Method: {pages}.</p>")
    parts.append("</section>")
    return "".join(parts)


def _evidence_row(ev: Evidence, experiments: dict) -> str:
    entry = experiments.get(ev.experiment)
    value = compare.lookup(entry.get("metrics", {}), ev.metric) if entry else None
    shown = ("not run" if entry is None else ev.none_text if value is None
             else "not measured in this run" if compare.is_missing(value)
             else fmt(value, ev.unit))
    return (f"<tr><td><a href='#{anchor(ev.experiment)}'>{escape(ev.experiment)}</a></td>"
            f"<td>{escape(ev.label)}</td><td class='num wrap'>{escape(shown)}</td></tr>")


def difference_section(diff: Difference, experiments: dict) -> str:
    rows = "".join(_evidence_row(e, experiments) for e in diff.evidence)
    table = ("<table><thead><tr><th>experiment</th><th>evidence</th><th>ours</th></tr></thead>"
             f"<tbody>{rows}</tbody></table>") if rows else ""
    pages = ", ".join(f"<code>docs/{escape(p)}</code>" for p in diff.pages)
    return (f'<section id="{diff.anchor}"><h3>{escape(diff.title)}</h3>'
            f"<p><strong>The seeds.</strong> {escape(diff.seeds)}</p>"
            f"<p><strong>Ours.</strong> {escape(diff.ours)}</p>"
            f"<p><strong>Why.</strong> {escape(diff.why)}</p>{table}"
            f"{'<p class=muted>More: ' + pages + '.</p>' if pages else ''}</section>")


def pending_section(registry: dict, experiments: dict) -> str:
    waiting = {k: v for k, v in PENDING.items() if k not in registry and k not in experiments}
    if not waiting:
        return ""
    rows = []
    for name, claim in waiting.items():
        published = "<br>".join(f"{escape(p.label)}: {escape(p.text)} ({escape(p.source)})"
                                for p in claim.published) or "no published number"
        rows.append(f"<tr><td>{escape(name)}</td><td>{escape(claim.source)}</td>"
                    f"<td>{escape(claim.claim)}</td><td>{published}</td></tr>")
    return ('<section id="pending"><h2>Seed claims not reproduced yet</h2>'
            "<p>No experiment of this results folder tests these; they are listed so that every "
            "published figure the project tracks appears in this report.</p>"
            "<table><thead><tr><th>planned experiment</th><th>source</th><th>claim</th>"
            f"<th>published</th></tr></thead><tbody>{''.join(rows)}</tbody></table></section>")


def provenance_section(provenance: dict | None, built: dict) -> str:
    def table(d: dict) -> str:
        rows = "".join(f"<tr><th>{escape(str(k))}</th><td class='wrap'>"
                       f"{escape(_prov_value(v))}</td></tr>" for k, v in d.items())
        return f"<table><tbody>{rows}</tbody></table>"

    if provenance:
        run = table(provenance)
    else:
        run = ("<p class='callout'>This results.json records no provenance (it was written by "
               "an older version of <code>verticality reproduce</code>): version, commit, "
               "libraries, machine, date and mode of the run are unknown.</p>")
    return ('<section id="provenance"><h2>Provenance</h2><h3>The run</h3>' + run +
            "<h3>This page</h3>" + table(built) + "</section>")


def _prov_value(value: Any) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{k} {_prov_value(v)}" for k, v in value.items())
    if isinstance(value, list):
        return ", ".join(_prov_value(v) for v in value)
    if value is None:
        return "unknown"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return str(value)


# ---------------------------------------------------------------------------------------------
# the page


def render(results: dict, results_dir: Path, built: dict) -> str:
    """The whole page for a loaded ``results.json`` (figures looked up under ``results_dir``)."""
    experiments = results.get("experiments", {})
    registry = results.get("registry") or {n: {} for n in experiments}
    provenance = results.get("provenance")
    names = ordered_names(registry, experiments)
    summary, statuses = [], []
    for name in names:
        row, status = summary_row(name, registry, experiments)
        summary.append(row)
        statuses.append(status)
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in compare.STATUSES if s in statuses)
    mode = (provenance or {}).get("mode", "unknown")
    version = (provenance or {}).get("version", "unknown")
    git = (provenance or {}).get("git") or {}
    commit = git.get("commit") if isinstance(git, dict) else None
    commit = commit[:12] if isinstance(commit, str) else ""  # (a damaged file: no commit shown)
    quick_note = ("<p class='callout'>Quick mode: shorter runs and fewer Monte Carlo "
                  "repetitions, so the numbers are not the ones of docs/reproduction.md; run "
                  "<code>verticality reproduce</code> without <code>--quick</code> for those.</p>"
                  if mode == "quick" else "")
    failed = [f"{n}: {'.'.join(p)}" for n in names if n in experiments
              for p, c in compare.checks(experiments[n].get("metrics", {})) if not c.get("pass")]
    failed_note = (f"<p class='callout'>Failed checks: {escape('; '.join(failed))}.</p>"
                   if failed else "")
    legend = ("<p class='muted'>Status: " + " ".join(badge(s) for s in compare.STATUSES[:5]) +
              " — a verdict judges the seed's finding (a ratio, a region, a sign, a bound) "
              "under the setting marked beside ours: <em>seed's reading</em> (the seed's own "
              "setting, as we read it), <em>ours</em> (our improved setting, shown beside it) or "
              "<em>another reading</em> of the seed's words; an experiment's verdict rests on "
              "the seed's reading. <em>better</em>: under the seed's reading, ours beats an "
              "approximate published figure by more than a quarter; <em>meets</em>: at or "
              "within the published figure or bound; <em>differs</em>: outside it (see “Where "
              "we differ”); <em>our setting</em>: a magnitude under our setting, another "
              "experiment, not judged; <em>not measured</em>: "
              "this run lacks the metric (a quick run skips some); <em>not run</em>: the "
              "experiment is not in this results folder. Checks are the project's own pass/fail "
              "tests.</p>")
    summary_table = ("<table class='summary'><thead><tr><th>experiment</th><th>seed claim</th>"
                     "<th>what is compared</th><th>published</th><th>ours</th><th>status</th>"
                     "<th>checks</th></tr></thead><tbody>"
                     + "".join(summary) + "</tbody></table>")
    sections = "".join(experiment_section(n, registry, experiments, results_dir) for n in names)
    differences = "".join(difference_section(d, experiments) for d in DIFFERENCES)
    pending = pending_section(registry, experiments)
    differ_links = "; ".join(f'<a href="#{d.anchor}">{escape(d.title)}</a>' for d in DIFFERENCES)
    title = "verticality — reproduction report"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title><style>{_STYLE}</style></head>
<body><nav class="top"><a href="#summary">Summary</a><a href="#experiments">Experiments</a>
<a href="#differ">Where we differ</a>{'<a href="#pending">Not reproduced yet</a>'
                                     if pending else ''}
<a href="#provenance">Provenance</a></nav><main>
<h1>{escape(title)}</h1>
<p class="meta">verticality {escape(str(version))}{' · commit ' + escape(commit) if commit else ''}
 · {escape(str(mode))} mode · {escape(str((provenance or {}).get('date_utc', 'date unknown')))}
 · {len(experiments)} experiments run</p>
<p>What the four seed documents (T, F, P11, P13; see <code>docs/references.md</code>) claim, what
we measured, and where we agree and differ. The protocol of every experiment is
<code>docs/reproduction.md</code>; published figures are a floor, not a target.</p>
{quick_note}{failed_note}
<section id="summary"><h2>Summary</h2><p>{escape(counts)}.</p>{legend}{summary_table}
<p><strong>Where we differ from the seeds:</strong> {differ_links}.</p></section>
<div id="experiments">{sections}</div>
<section id="differ"><h2>Where we differ from the seeds</h2>
<p>Each difference with the seeds' statement, ours, the reason, and the numbers of this run that
show it.</p>{differences}</section>
{pending}
{provenance_section(provenance, built)}
</main></body></html>
"""
