"""The reproduction report and the documentation site as a person sees them: each opened from disk
in a real headless Chromium (Debian's ``chromium``, driven by tests/headless_chromium.py), with
no console error, every experiment of `verticality list` in its section with a figure that is
not blank, and screenshots saved in the test's temporary folder.

The report comes from one quick ``verticality reproduce`` run in this process, shared by the
tests of this module; ``VERTICALITY_QUICK_RESULTS=DIR`` reuses the results folder of an earlier
quick run instead (the report is rebuilt from it)."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from headless_chromium import Chromium, find_chromium
from verticality import cli, experiments
from verticality.report import compare

ROOT = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"


def in_ci() -> bool:
    """True under a CI runner (``CI=true``, as .ci/run and the usual CI services set it)."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def _require(ok: bool, what: str) -> None:
    """A missing tool skips the test with a one-line reason on a user's machine (the README's test
    command installs chromium where it can: .ci/install-chromium); under CI it fails, so that CI
    never passes without the pages having been opened."""
    if not ok:
        message = f"{what} is not installed (.ci/install-chromium, or CHROMIUM=/path/to/it)"
        if in_ci():
            pytest.fail(message)
        pytest.skip(message)


@pytest.fixture(scope="module")
def browser():
    binary = find_chromium()
    _require(binary is not None, "chromium (Debian package `chromium`)")
    with Chromium(binary) as b:
        yield b


@pytest.fixture(scope="module")
def quick_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("quick-results")
    reuse = os.environ.get("VERTICALITY_QUICK_RESULTS")
    if reuse:
        shutil.copytree(reuse, out, dirs_exist_ok=True)
        (out / "report.html").unlink(missing_ok=True)
        assert cli.main(["report", str(out)]) == 0
    else:
        # in this process (--jobs 1): the suite's other worker has the second core, and the
        # workers' path is tests/test_reproduce_parallel.py's (the same results, bit for bit)
        assert cli.main(["reproduce", "--quick", "--jobs", "1", "--out", str(out)]) in (0, 1)
    return out


def _shot(page, path: Path, **kw) -> Path:
    page.screenshot(path, **kw)
    data = path.read_bytes()
    assert data.startswith(PNG) and len(data) > 10_000, path
    return path


# The page's own view of each experiment section: its figures, decoded and drawn into a canvas
# to count the pixels that are not background.
_SECTIONS_JS = """
(async () => {
  const out = {};
  for (const s of document.querySelectorAll('section[id^="exp-"]')) {
    const figs = [];
    for (const img of s.querySelectorAll('figure img')) {
      await img.decode().catch(() => null);
      let inked = 0;
      if (img.naturalWidth > 0) {
        const c = document.createElement('canvas');
        c.width = 200;
        c.height = Math.max(1, Math.round(200 * img.naturalHeight / img.naturalWidth));
        const g = c.getContext('2d');
        g.drawImage(img, 0, 0, c.width, c.height);
        const px = g.getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 0; i < px.length; i += 4) if (px[i] + px[i + 1] + px[i + 2] < 720) n++;
        inked = n / (c.width * c.height);
      }
      const r = img.getBoundingClientRect();
      figs.push({w: img.naturalWidth, h: img.naturalHeight, shownW: r.width, inked});
    }
    out[s.id] = {figs, text: s.innerText.length};
  }
  const status = {};
  for (const a of document.querySelectorAll('#summary a[href^="#exp-"]')) {
    const row = a.closest('tr');
    status[a.getAttribute('href').slice(1)] = row.querySelector('.status').innerText;
  }
  return {sections: out, status, title: document.title,
          height: document.documentElement.scrollHeight};
})()
"""


def test_report_of_a_quick_run_in_chromium(browser, quick_results, tmp_path):
    page_file = quick_results / "report.html"
    assert 100_000 < page_file.stat().st_size < 10_000_000
    page = browser.open(page_file.as_uri())
    seen = page.evaluate(_SECTIONS_JS)
    assert page.errors() == []
    assert seen["title"] == "verticality — reproduction report"
    names = sorted(experiments.discover())
    assert names
    for name in names:
        section = seen["sections"].get(f"exp-{name}")
        assert section is not None, f"{name} has no section"
        assert section["text"] > 200, name
        assert section["figs"], f"{name} shows no figure"
        for fig in section["figs"]:
            assert fig["w"] > 100 and fig["h"] > 100 and fig["shownW"] > 100, (name, fig)
            assert fig["inked"] > 0.01, (name, fig)  # a drawn figure, not a blank image
        assert seen["status"].get(f"exp-{name}") in compare.STATUSES, name
    for shot, kw in (("report-top.png", {}), ("report-summary.png", {"selector": "#summary"}),
                     ("report-differ.png", {"selector": "#differ"}),
                     ("report-full.png", {"full_page": True})):
        _shot(page, tmp_path / shot, **kw)


def _build_site(out: Path) -> Path:
    _require(importlib.util.find_spec("mkdocs") is not None, "mkdocs (the docs extra)")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f",
                          str(ROOT / "mkdocs.yml"), "-d", str(out)], capture_output=True,
                         text=True, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "WARNING" not in run.stderr, run.stderr[-3000:]
    return out


def test_documentation_site_in_chromium(browser, tmp_path):
    site = _build_site(tmp_path / "site")
    pages = {
        "index.html": ("verticality", "Getting started"),
        "getting-started.html": ("verticality reproduce --quick", "verticality report"),
        "tutorials/reproduce.html": ("Where we differ", "provenance"),
        "tutorials/extend.html": ("model_dataclass", "split_measurement"),
        "api/models.html": ("model_dataclass", "EuclideanState"),
        "api/estimators.html": ("split_measurement", "scan_steps"),
        "api/report.html": ("Published", "verdict"),
        "ekf.html": ("EKF on SO(3)", "ekf-sensitivity"),
    }
    for rel, expected in pages.items():
        page = browser.open((site / rel).as_uri())
        text = page.evaluate("document.body.innerText")
        assert page.errors() == [], rel
        for phrase in expected:
            assert phrase in text, (rel, phrase)
        links = page.evaluate("[...document.querySelectorAll('nav a[href]')].length")
        assert links > 20, rel  # the site's navigation is there
        if rel.startswith("api/") and rel != "api/index.html":
            # one section per module of the package, anchored by its dotted path
            package = "verticality." + Path(rel).stem
            modules = page.evaluate(
                f"[...document.querySelectorAll('[id^=\"{package}.\"]')].map(e => e.id)")
            assert f"{package}.base" in modules or len(modules) >= 3, (rel, modules)
        _shot(page, tmp_path / (rel.replace("/", "-") + ".png"))
    # the search works from disk too (the worker shim is part of the site)
    page = browser.open((site / "index.html").as_uri())
    hits = page.evaluate(_SEARCH_JS % "observability")
    assert hits >= 3 and page.errors() == []
    _shot(page, tmp_path / "search.png")


_SEARCH_JS = """
(async () => {
  const box = document.querySelector('input[data-md-component=search-query]');
  box.focus(); box.value = '%s';
  box.dispatchEvent(new Event('input', {bubbles: true}));
  box.dispatchEvent(new KeyboardEvent('keyup', {bubbles: true, key: 'y'}));
  for (let i = 0; i < 100; i++) {
    const n = document.querySelectorAll('.md-search-result__item').length;
    if (n) return n;
    await new Promise(r => setTimeout(r, 100));
  }
  return 0;
})()
"""
