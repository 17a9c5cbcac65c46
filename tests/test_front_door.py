"""What a new user meets first: the README's test command is the one CI runs, and it installs
every package the tests import."""

import ast
import importlib.metadata as md
import re
import sys
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"


def readme_command(number: int) -> str:
    """The command under ``# NUMBER.`` in the README's quick start."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(f"# {number}."))
    return lines[i + 1]


def test_ci_runs_the_readmes_test_command_verbatim():
    command = readme_command(2)
    assert "pip install" in command and "pytest" in command
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert command in ci  # a line of its own, character for character
    assert "export CI=true MPLBACKEND=Agg" in ci  # there the browser tests must run
    # the getting-started page gives the same command
    start = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8").splitlines()
    assert command in start


def _requirements_of_the_test_extra() -> list[Requirement]:
    """The project's dependencies and its ``test`` extra, self-references expanded (from
    pyproject.toml: the installed metadata may be another checkout's)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras, out, todo, seen = project["optional-dependencies"], [], ["test"], set()
    out += [Requirement(r) for r in project["dependencies"]]
    while todo:
        extra = todo.pop()
        if extra in seen:
            continue
        seen.add(extra)
        for r in map(Requirement, extras[extra]):
            if canonicalize_name(r.name) == "verticality":
                todo += sorted(r.extras)
            else:
                out.append(r)
    return out


def _installed_closure(reqs) -> set[str]:
    """Names of the distributions those requirements bring in (as installed here, recursively,
    with the extras they ask for)."""
    names, todo, seen = set(), list(reqs), set()
    while todo:
        r = todo.pop()
        key = (canonicalize_name(r.name), frozenset(r.extras))
        if key in seen:
            continue
        seen.add(key)
        names.add(key[0])
        try:
            requires = md.distribution(r.name).requires or []
        except md.PackageNotFoundError:
            continue
        for sub in map(Requirement, requires):
            if sub.marker is None or any(sub.marker.evaluate({"extra": e})
                                         for e in (*r.extras, "")):
                todo.append(sub)
    return names


def _modules_the_tests_import() -> set[str]:
    local = {p.stem for p in TESTS.glob("*.py")} | {"verticality"}
    found = set()
    for path in TESTS.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
            elif (isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "find_spec"
                  and node.args and isinstance(node.args[0], ast.Constant)):
                found.add(str(node.args[0].value).split(".")[0])
    return found - local - set(sys.stdlib_module_names) - {"__future__"}


def test_the_readmes_test_command_installs_what_the_tests_import():
    """Every package a test imports (the peers vqf, ahrs and imufusion, Dask, mkdocs…) comes with
    `pip install -e ".[test]"`, so that no test fails or is skipped for want of one."""
    assert '".[test]"' in readme_command(2)
    provided = _installed_closure(_requirements_of_the_test_extra())
    by_module = md.packages_distributions()
    missing = {m: by_module.get(m, ["(not installed)"]) for m in _modules_the_tests_import()
               if not {canonicalize_name(d) for d in by_module.get(m, [])} & provided}
    assert missing == {}
    assert {"vqf", "ahrs", "imufusion", "distributed", "mkdocs"} <= provided


def test_the_broad_slices_are_small_and_attributed():
    data = TESTS / "data" / "broad"
    size_mb = sum(p.stat().st_size for p in data.glob("*.hdf5")) / 1e6
    assert 0 < size_mb < 4.0
    readme = (data / "README.md").read_text(encoding="utf-8")
    assert "CC BY 4.0" in readme and "Laidig" in readme
    assert (data / "LICENSE-CC-BY-4.0.txt").is_file()
    assert re.search(r"BROAD.*CC BY 4\.0", (ROOT / "README.md").read_text(encoding="utf-8"),
                     re.S)
