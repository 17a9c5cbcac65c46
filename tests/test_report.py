"""The reproduction report: claims table, verdicts, the page built from a results folder, the
`report` command and provenance. The page in a real browser: tests/test_report_browser.py."""

import datetime as dt
import json
import re
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from verticality import cli, experiments, report  # noqa: E402
from verticality.core.errors import InputError  # noqa: E402
from verticality.report import compare, provenance  # noqa: E402
from verticality.report.claims import CLAIMS, DIFFERENCES, PENDING, Published  # noqa: E402
from verticality.report.html import anchor  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"


# ---------------------------------------------------------------------------------------------
# a small results folder, made here


def _png(path: Path, label: str) -> Path:
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1], label=label)
    ax.set_xlabel("time (s)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=40)
    plt.close(fig)
    return path


def _results(tmp_path: Path, names=("newton-lissajous", "separation", "observability")) -> Path:
    """results.json and one figure per experiment, with metrics at the claims' paths."""
    metrics = {
        "newton-lissajous": {
            "max_tilt_error_deg": {"fixed": {"exact": 1e-6, "perturbed": 3.4},
                                   "stabilized": {"exact": 4e-5, "perturbed": 0.6}},
            "ratio_fixed_over_stabilized": {"perturbed": 5.7},
            "checks": {"stabilized.perturbed": {"value": 0.6, "tolerance": 0.5, "pass": False}}},
        "separation": {"unstable": {"sensor_feedback": True, "state_feedback": False},
                       "max_error_rad": {"luenberger": {"ref1": 0.23, "ref0": 0.01}}},
        "observability": {"agreement": 14, "cases": 16,
                          "rows": [{"model": "medial", "control": "known",
                                    "orientation_observable": True}]},
    }
    entries = {}
    for name in names:
        fig = _png(tmp_path / name / f"{name}.png", name)
        entries[name] = {"metrics": metrics.get(name, {"x": 1.0}), "paper": {"x": 2.0},
                         "runtime": {"wall_s": 1.5, "simulated_s": 10.0},
                         "figures": [str(fig)]}
    registry = {n: {"title": f"title of {n}", "source": "somewhere"} for n in names}
    data = {"experiments": entries, "registry": registry,
            "provenance": provenance.collect(quick=True)}
    (tmp_path / "results.json").write_text(json.dumps(data))
    return tmp_path


class _Page(HTMLParser):
    """Ids, references (src/href) and the text of each section of a page."""

    def __init__(self):
        super().__init__()
        self.ids, self.refs, self.text_by_section = set(), [], {}
        self._open: list[str | None] = []  # the section tags open, by id

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        for key in ("src", "href"):
            if key in a:
                self.refs.append(a[key])
        if tag == "section":
            self._open.append(a.get("id"))
            self.text_by_section.setdefault(a.get("id"), "")

    def handle_endtag(self, tag):
        if tag == "section" and self._open:
            self._open.pop()

    def handle_data(self, data):
        for section in self._open:  # nested sections: the text belongs to each
            self.text_by_section[section] += data


def _parse(page: str) -> _Page:
    p = _Page()
    p.feed(page)
    return p


# ---------------------------------------------------------------------------------------------
# the claims table


def test_every_claim_names_a_registered_experiment_and_every_difference_cites_one():
    registered = set(experiments.discover())
    assert set(CLAIMS) <= registered, set(CLAIMS) - registered
    assert not set(PENDING) & registered  # a registered experiment moves to CLAIMS
    for diff in DIFFERENCES:
        assert diff.evidence and {e.experiment for e in diff.evidence} <= registered


def _numbers(text: str) -> set[float]:
    text = text.replace("−", "-")
    return {float(m) for m in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", text)}


def _published_passages(md: str):
    """(experiment names, published passage) per section of docs/reproduction.md."""
    for block in md.split("\n### ")[1:]:
        header, body = block.split("\n", 1)
        names = re.findall(r"`([a-z0-9-]+)`", header)
        body = " ".join(body.split())
        for m in re.finditer(r"(Published[^:]*:|(?:T|P13) \(Fig\.[^)]*\):?)(.*?)(?=Checks?:|$)",
                             body):
            yield names, m.group(2)


def test_every_published_number_of_the_protocol_is_in_the_claims_table():
    """docs/reproduction.md's published figures, each beside ours: every number of its
    "Published" passages (document references — figure, equation, table, section numbers —
    left out) is in the published text or the label of one of that section's claims."""
    passages = list(_published_passages((DOCS / "reproduction.md").read_text()))
    assert len(passages) >= 6
    checked = 0
    for names, passage in passages:
        claims = [CLAIMS[n] for n in names if n in CLAIMS]
        assert claims, names
        ours = set()
        for c in claims:
            for p in c.published:
                ours |= _numbers(f"{p.label} {p.text}")
        stripped = re.sub(r"(Tables?|Fig\.|eq\.|§)\s*[\d.–-]+|SO\(3\)", "", passage)
        published = _numbers(stripped)
        checked += len(published)
        missing = {x for x in published if not any(abs(x - y) <= 1e-12 * max(1, abs(x))
                                                   for y in ours)}
        assert not missing, (names, missing, passage)
    assert checked >= 20


def test_published_values_agree_with_the_texts_they_print():
    """A published number used for a verdict is the number its text shows (no silent drift)."""
    for name, claim in CLAIMS.items():
        for p in claim.published:
            if p.kind in ("approx_error", "at_most") and p.value is not None and "(" not in p.text:
                assert _numbers(p.text) & {float(p.value)}, (name, p.label)


# ---------------------------------------------------------------------------------------------
# verdicts


def _pub(kind, value, **kw):
    return Published("x", "src", "text", ("m",), kind, value, **kw)


@pytest.mark.parametrize(("kind", "value", "ours", "status"), [
    ("approx_error", 3.0, 1.0, "better"), ("approx_error", 3.0, 3.5, "meets"),
    ("approx_error", 3.0, 4.0, "differs"), ("approx_error", 3.0, None, "differs"),
    ("at_most", 0.5, 0.5, "meets"), ("at_most", 0.5, 0.51, "differs"),
    ("at_least", 10.0, 13.9, "meets"), ("at_least", 16, 14, "differs"),
    ("equals", True, True, "meets"), ("equals", 20, None, "differs"),
    ("within", [[1.0, 2.0]], [[1.04, 1.95]], "meets"),
    ("within", [[1.0, 2.0]], [[1.2, 2.0]], "differs"),
    ("within", [[1.0, 2.0]], [1.0, 2.0], "differs"), ("context", 0.15, 0.25, "not judged"),
    ("context", None, 0.25, "no published number"),
])
def test_verdicts(kind, value, ours, status):
    pub = _pub(kind, value, rel=0.05 if kind == "within" else 0.25)
    assert compare.verdict(compare.ours({"m": ours}, pub), pub) == status


def test_lookup_reduce_ratio_and_missing():
    metrics = {"a": {"sigma_0.001": [1.0, None, 3.0]}, "c": {"value": 2.0, "tol": 1, "pass": True},
               "rows": [{"k": 5}]}
    assert compare.lookup(metrics, ("c",)) == 2.0  # a check gives its value
    assert compare.lookup(metrics, ("rows", 0, "k")) == 5
    assert compare.is_missing(compare.lookup(metrics, ("a", "nope")))
    assert compare.is_missing(compare.lookup(metrics, ("rows", 3, "k")))
    pub = Published("x", "s", "t", ("a", "sigma_0.001"), "at_most", 3.0, reduce="max")
    assert compare.ours(metrics, pub) == 3.0 and compare.verdict(3.0, pub) == "meets"
    ratio = Published("x", "s", "t", ("c",), "at_most", 1.0, ratio_to=("rows", 0, "k"))
    assert compare.ours(metrics, ratio) == pytest.approx(0.4)
    gone = Published("x", "s", "t", ("renamed",), "at_most", 1.0)
    assert compare.verdict(compare.ours(metrics, gone), gone) == "not measured"
    shown = Published("x", "s", "t", ("renamed",))  # nothing to judge: no verdict either way
    assert compare.verdict(compare.ours(metrics, shown), shown) == "no published number"
    assert compare.overall(["meets", "better", "no published number"]) == "better"
    assert compare.overall(["better", "differs"]) == "differs"
    assert compare.overall([]) == "no published number"
    assert compare.overall(["meets"], ran=False) == "not run"


def _row(kind, value, ours, setting="seed"):
    pub = _pub(kind, value, setting=setting)
    return compare.Row(pub, ours, compare.verdict(ours, pub))


def test_a_finding_is_judged_under_the_seeds_reading():
    """A region reproduced under the seed's reading meets, whatever another reading gives; not
    reproduced, it differs, whatever our setting gives."""
    region = [_row("at_least", 12.0, 12.0), _row("at_most", 25.0, 16.0)]
    other = [_row("at_least", 12.0, None, "alt"), _row("at_most", 25.0, 0.0, "ours")]
    assert [r.status for r in region] == ["meets", "meets"] and other[0].status == "differs"
    assert compare.overall_rows(region + other) == "meets"
    assert compare.overall([r.status for r in region + other]) == "differs"  # unweighted
    lost = [_row("at_least", 12.0, 8.0), _row("at_least", 10.0, 13.0, "ours")]
    assert compare.overall_rows(lost) == "differs"
    # a ratio (a finding) is judged under our setting too; the experiment rests on neither
    # when the seed's reading has no judged figure
    ratio = [_row("at_least", 10.0, 13.0, "ours"), _row("context", None, 1.0)]
    assert ratio[0].status == "meets" and compare.overall_rows(ratio) == "meets"


def test_better_only_under_the_seeds_own_setting():
    """A magnitude far below the published one under our setting is another experiment: shown as
    ours, not as better."""
    seed, ours = _row("approx_error", 3.0, 0.37), _row("approx_error", 3.0, 2.9e-6, "ours")
    assert seed.status == "better" and ours.status == "our setting"
    assert _row("approx_error", 3.0, 9.0, "alt").status == "our setting"
    assert compare.overall_rows([ours]) == "our setting"
    assert compare.overall_rows([seed, ours]) == "better"
    assert compare.overall_rows([_row("approx_error", 3.0, 9.0), ours]) == "differs"


def test_the_page_marks_the_setting_of_every_figure(tmp_path, monkeypatch):
    from verticality.report import html
    from verticality.report.claims import Claim

    claim = Claim(source="P11", claim="c", published=(
        Published("fixed, P11's reading", "P11 Fig. 4", "≈ 3°", ("a",), "approx_error", 3.0,
                  unit="°", headline=True),
        Published("fixed, ours", "P11 Fig. 4", "≈ 3°", ("b",), "approx_error", 3.0, unit="°",
                  setting="ours", headline=True)))
    rows = compare.rows(claim, {"a": 0.4, "b": 3e-6})
    table = html.comparison_table(rows)
    assert "<th>setting</th>" in table
    assert "seed&#x27;s reading" in table and "setting-ours" in table and "our setting" in table
    monkeypatch.setitem(html.CLAIMS, "x-exp", claim)
    summary, status = html.summary_row("x-exp", {"x-exp": {"title": "t"}},
                                       {"x-exp": {"metrics": {"a": 0.4, "b": 3e-6}}})
    assert status == "better" and "setting-ours" in summary and "setting-seed" in summary


# ---------------------------------------------------------------------------------------------
# the page


def test_page_has_every_section_status_and_figure_and_needs_no_network(tmp_path):
    results = _results(tmp_path)
    page = report.build(results).read_text()
    parsed = _parse(page)
    for name in ("newton-lissajous", "separation", "observability"):
        assert anchor(name) in parsed.ids
        assert f'href="#{anchor(name)}"' in page  # linked from the summary
    assert {"summary", "differ", "provenance"} <= parsed.ids
    # every reference stays inside the page: anchors and embedded images, nothing to fetch
    assert parsed.refs and all(r.startswith(("#", "data:image/")) for r in parsed.refs)
    assert page.count('<img src="data:image/png;base64,') == 3
    summary = parsed.text_by_section["summary"]
    # newton-lissajous: fixed perturbed 3.4 vs ≈ 6° is better, stabilized 0.6 vs < 0.5 differs
    assert "differs" in parsed.text_by_section[anchor("newton-lissajous")]
    assert "3.4°" in summary and "≈ 6°" in summary and "0.6°" in summary
    assert "1 of 1 pass" not in summary and "0 of 1 pass" in summary  # the failed check shows
    assert "Failed checks: newton-lissajous: checks.stabilized.perturbed" in page
    # published figures of every claim sit in their experiment's section
    for name in ("newton-lissajous", "separation", "observability"):
        section = parsed.text_by_section[anchor(name)]
        for pub in CLAIMS[name].published:
            assert pub.text in section, (name, pub.text)
    # differences show this run's numbers as evidence; a metric the run lacks says so
    differ = parsed.text_by_section["differ"]
    assert "14 of 16" in differ and "not run" in differ and "not measured in this run" in differ
    assert "Quick mode" in page  # the run's mode is stated


def test_registered_but_not_run_and_unclaimed_experiments_are_covered(tmp_path, monkeypatch):
    from verticality.report import claims, html

    # every seed claim has its experiment now: a pending one stands in for a later seed
    monkeypatch.setattr(html, "PENDING", {"vection": claims.Claim(
        source="a later seed", claim="Visual vection paradigms against the somatogravic model.")})
    results = _results(tmp_path, names=("separation", "brand-new"))
    data = json.loads((results / "results.json").read_text())
    data["registry"]["ekf-impact"] = {"title": "EKF", "source": "P13 §5"}
    (results / "results.json").write_text(json.dumps(data))
    parsed = _parse(report.build(results).read_text())
    summary = parsed.text_by_section["summary"]
    assert "brand-new" in summary and "no published number" in summary
    assert "not run" in parsed.text_by_section[anchor("ekf-impact")]
    assert "No seed claim is recorded" in parsed.text_by_section[anchor("brand-new")]
    # the seed claims without an experiment are listed with their published figures
    assert "vection" in parsed.text_by_section["pending"]
    assert "somatogravic" in parsed.text_by_section["pending"]


def test_moved_folder_missing_figure_old_results_and_hostile_text(tmp_path):
    src = _results(tmp_path / "a", names=("separation", "platform"))
    moved = tmp_path / "b"
    src.rename(moved)  # recorded figure paths now point into a folder that no longer exists
    (moved / "platform" / "platform.png").unlink()
    data = json.loads((moved / "results.json").read_text())
    del data["provenance"], data["registry"]
    data["experiments"]["separation"]["metrics"]["<script>alert(1)</script>"] = "<b>x</b>"
    (moved / "results.json").write_text(json.dumps(data))
    page = report.build(moved, tmp_path / "out" / "r.html").read_text()
    assert page.count("data:image/png;base64,") == 1  # separation's, found beside results.json
    assert "figure missing" in page and "verticality reproduce platform" in page
    assert "records no provenance" in page
    assert "<script" not in page and "&lt;script&gt;" in page


def test_load_errors_are_one_line(tmp_path, capsys):
    with pytest.raises(InputError, match="no results.json"):
        report.load_results(tmp_path)
    (tmp_path / "results.json").write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        report.load_results(tmp_path)
    (tmp_path / "results.json").write_text('{"something": 1}')
    assert cli.main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a results file" in err


def test_report_command_prints_the_path(tmp_path, capsys):
    results = _results(tmp_path)
    target = tmp_path / "elsewhere" / "page.html"
    assert cli.main(["report", str(results), "--out", str(target)]) == 0
    assert capsys.readouterr().out.strip() == str(target)
    assert target.stat().st_size > 10_000
    assert cli.main(["report", str(results)]) == 0
    assert Path(capsys.readouterr().out.strip()) == results / "report.html"


# ---------------------------------------------------------------------------------------------
# provenance


def test_provenance_records_versions_commit_machine_date_and_mode():
    import jax
    import numpy as np

    when = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.UTC)
    p = provenance.collect(quick=False, names=["separation"], now=when)
    assert p["mode"] == "full" and p["experiments_requested"] == ["separation"]
    assert p["date_utc"] == "2026-01-02T03:04:05+00:00"
    assert p["libraries"]["jax"] == jax.__version__ and p["libraries"]["numpy"] == np.__version__
    assert p["machine"]["cpus"] >= 1 and isinstance(p["jax_backend"], str)
    json.dumps(p)  # plain JSON
    head = subprocess.run(["git", "-C", str(Path(provenance.__file__).parent), "rev-parse",
                           "HEAD"], capture_output=True, text=True)
    if head.returncode == 0:
        assert p["git"]["commit"] == head.stdout.strip()
    else:
        assert p["git"] is None


def test_provenance_outside_a_work_tree_and_without_a_library(tmp_path):
    assert provenance.git_commit(tmp_path) is None
    assert provenance.library_versions(("no-such-distribution-x",)) == {
        "no-such-distribution-x": None}


def test_docs_hook_lets_a_list_follow_a_paragraph_line():
    import importlib.util

    spec = importlib.util.spec_from_file_location("lists_hook", DOCS / "hooks" / "lists.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    text = "Consequences:\n- one\n- two\nthat wraps\n- three\n\nAfter.\n1. first"
    assert hook.breakless_lists(text) == ("Consequences:\n\n- one\n- two\nthat wraps\n- three\n\n"
                                          "After.\n\n1. first")
    untouched = "```\ncode line\n- not a list\n```\n| a |\n- x\n# T\n- y\n\n- z"
    assert hook.breakless_lists(untouched) == untouched


def test_every_published_figure_shown_without_a_verdict_says_why():
    """A published figure beside ours is judged, or its row says plainly why it is not: a reader
    must not take the experiment's verdict for a row that was never compared."""
    from verticality.report.claims import CLAIMS

    unexplained = []
    for name, claim in CLAIMS.items():
        for pub in claim.published:
            if pub.kind != "context":
                continue
            shows_figure = pub.value is not None or any(c.isdigit() for c in pub.text) or (
                pub.text.strip("—“” ") not in ("", "no number", "no published number",
                                               "not published", "(no number)"))
            says_why = "not judged" in pub.text or "no number" in pub.text
            if shows_figure and not says_why:
                unexplained.append(f"{name}: {pub.label} = {pub.text}")
    assert unexplained == []
