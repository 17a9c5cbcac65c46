"""The architecture's promises (docs/architecture.md), checked on the code itself.

- One medial head–otolith value (``otolith_head.medial``) goes unchanged through the simulator, the
  EKF, the Newton observer, the linearization (→ ``control.StateSpace``), the observability test and
  the model checks.
- No module imports another module's private (``_name``) objects; no import cycle inside the
  package; float64 is switched on in one place; nothing points to files outside the repository.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import re
from pathlib import Path

import control
import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import model_checks as mc
from verticality.analysis import observability as obs
from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.estimators import ekf
from verticality.estimators.newton import NewtonConfig, NewtonObserver
from verticality.models import otolith_head
from verticality.models.base import Discretized
from verticality.models.gimbal import GimbalHead
from verticality.models.gimbal_plant import GimbalPlant
from verticality.models.head import HeadInput, HeadState
from verticality.models.linearize import linearize, to_statespace
from verticality.models.params import P13_HEAD, P13_PENDULUM
from verticality.models.pendulum import PendulumState
from verticality.simulation import closed_loop as sim
from verticality.simulation import trajectories as tr

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "verticality"

MEDIAL = otolith_head.medial(P13_PENDULUM, P13_HEAD, gyro=True)
"""The one value every algorithm below receives."""


def _upright():
    rest = (jnp.eye(3), jnp.zeros(3))
    return otolith_head.OtolithHeadState((PendulumState(*rest),), HeadState(*rest))


def test_one_medial_value_through_simulator_ekf_newton_linearization_observability_checks():
    # --- simulator: the plant is the value's head on the gimbal carrying the value's pendula
    plant = GimbalPlant(GimbalHead(MEDIAL.head), otolith_head.Otoliths(MEDIAL.pendula))
    la, ta = jax.tree_util.tree_flatten(plant)
    lb, tb = jax.tree_util.tree_flatten(sim.DEFAULT_PLANT)
    assert ta == tb and all(np.array_equal(a, b) for a, b in zip(la, lb, strict=True))

    # --- EKF on the same value (discretized), fed by the simulator in the loop
    model = Discretized(MEDIAL, substeps=4)
    filt = ekf.ExtendedKalmanFilter(model, ekf.block_covariance(1e-3, (3, 3, 3, 3)),
                                    0.02**2 * jnp.eye(ekf.N_Y), angle_outputs=MEDIAL.angle_outputs)
    est = sim.Estimator(step=filt.step, R_I_H=lambda s: s.x.head.R_I_H)
    cfg = sim.SimConfig(duration_s=2.0, condition="fixed", u_blocks=4)
    traj = tr.impact(duration_s=2.0)
    res = sim.make_simulator(traj, cfg, estimator=est)(
        jax.random.PRNGKey(0), plant, sim.noiseless(), filt.init(_upright(), 1e-4 * jnp.eye(12)))
    err_deg = np.asarray(res.record.tilt_error_deg)
    assert np.all(np.isfinite(err_deg)) and np.max(np.abs(err_deg)) < 1.0

    # --- Newton observer on the same discretized value: one window recovers the true state
    newton = NewtonObserver(model, HeadInput(jnp.zeros((4, 3)), jnp.zeros((4, 3))),
                            NewtonConfig(window=20, iterations=20))
    rng = np.random.default_rng(1)
    us = HeadInput(jnp.asarray(rng.normal(scale=0.02, size=(20, 4, 3))),
                   jnp.asarray(rng.normal(scale=2.0, size=(20, 4, 3))))
    x_true = otolith_head.OtolithHeadState(
        (PendulumState(so3.exp(jnp.array([0.05, -0.1, 0.0])), jnp.array([0.2, -0.1, 0.0])),),
        HeadState(so3.exp(jnp.array([0.1, 0.05, 0.3])), jnp.array([0.3, -0.2, 0.1])))
    # compiled, as the observer runs (op by op, its autodiff and while loop cost twice the time)
    ys = jax.jit(newton.observability_map)(x_true, us, 0.02)[0].reshape(20, ekf.N_Y)
    guess = model.retract(x_true, 0.02 * jnp.ones(12))
    sol = jax.jit(newton.solve)(guess, us, ys, jnp.ones_like(ys, dtype=bool), 0.02)
    assert float(jnp.max(jnp.abs(model.difference(sol.xi, x_true)))) < 1e-8

    # --- linearization at upright → control.StateSpace: the pendulum's poles at √(mgl/J) (damped)
    lin = linearize(MEDIAL, _upright(), HeadInput(jnp.zeros(3), jnp.zeros(3)))
    ss = to_statespace(lin)
    assert isinstance(ss, control.StateSpace) and ss.nstates == 12
    p = P13_PENDULUM.resolved()
    J = float(p.J_pivot_S[0])
    wn = np.sqrt(p.m_kg * G_M_S2 * p.l_m / J)
    zeta = p.beta_Nms / (2 * J * wn)
    poles = np.linalg.eigvals(np.asarray(lin.A))
    expected = wn * (-zeta + 1j * np.sqrt(1 - zeta**2))
    assert np.min(np.abs(poles - expected)) < 1e-6 * wn

    # --- observability: with an unknown constant acceleration a_H the tilt is not observable from
    # the otolith angles of a free, unactuated head (the tilt–translation ambiguity, F §3.2)
    prob = obs.Problem(
        model=dataclasses.replace(MEDIAL, gyro=False), state=_upright(), unknowns={"a_H": (3,)},
        input_map=lambda x, u, th: HeadInput(jnp.zeros(3), x.head.R_I_H @ th["a_H"]),
        quantities={"tilt": lambda x, th: x.head.R_I_H.T @ jnp.array([0.0, 0.0, 1.0])},
        sample=lambda g: (otolith_head.OtolithHeadState(
            (PendulumState(obs.random_rotation(g), g.standard_normal(3)),),
            HeadState(obs.random_rotation(g), g.standard_normal(3))),
            {"a_H": g.standard_normal(3)}))
    result = obs.analyze(prob, order=4, points=1)
    assert result.n_coords == 15 and 0 < result.rank < result.n_coords
    assert not result.quantities["tilt"].observable

    # --- model checks: the value's still-head run keeps the pendulum at rest, hanging
    still = dataclasses.replace(MEDIAL, gyro=False)
    _, xs = mc.run_model(still, _upright(), lambda t, x: HeadInput(jnp.zeros(3), jnp.zeros(3)),
                         1e-3, 200)
    np.testing.assert_allclose(np.asarray(xs.pendula[0].R_I_S),
                               np.broadcast_to(np.eye(3), (200, 3, 3)), atol=1e-12)


# ------------------------------------------------------------------------------ the code's shape
@functools.cache
def _modules() -> tuple:
    """(module name, path, syntax tree) of every module of the package, parsed once for the
    tests below (which only read the trees)."""
    out = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        out.append((".".join(parts), path, ast.parse(path.read_text(encoding="utf-8"))))
    return tuple(out)


def _resolve(module: str, path: Path, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if path.name != "__init__.py":
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def test_no_module_imports_another_modules_private_objects():
    offenders = []
    for module, path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                src = _resolve(module, path, node)
                if not src.startswith("verticality") or src == module:
                    continue
                offenders += [f"{module}: from {src} import {a.name}" for a in node.names
                              if a.name.startswith("_") and not a.name.startswith("__")]
        # attribute access on an imported verticality module: mod._name
        aliases = {a.asname or a.name.split(".")[-1]
                   for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))
                   for a in node.names
                   if (isinstance(node, ast.Import) and a.name.startswith("verticality"))
                   or (isinstance(node, ast.ImportFrom)
                       and _resolve(module, path, node).startswith("verticality")
                       and (SRC.parent / Path(*_resolve(module, path, node).split("."),
                                              a.name)).exists())}
        offenders += [f"{module}: {node.value.id}.{node.attr}" for node in ast.walk(tree)
                      if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                      and node.value.id in aliases and node.attr.startswith("_")
                      and not node.attr.startswith("__")]
    assert offenders == []


def test_no_import_cycle_in_the_package():
    """Imports inside functions count: a lazy import still ties the two modules together (the
    cycle only waits for the first call). Imports for type checkers only (``if TYPE_CHECKING:``)
    do not: they never run."""
    graph = {}
    for module, path, tree in _modules():
        deps = set()
        typing_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                       and ast.unparse(block.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING")
                       for statement in block.body for n in ast.walk(statement)}
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.ImportFrom):
                src = _resolve(module, path, node)
                deps |= {f"{src}.{a.name}" for a in node.names} | {src}
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
        graph[module] = deps
    graph = {m: {d for d in ds if d in graph and d != m and not m.startswith(d + ".")}
             for m, ds in graph.items()}
    state: dict[str, int] = {}

    def visit(m, stack):
        state[m] = 1
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                raise AssertionError("import cycle: " + " → ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d, stack + [d])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


def test_the_package_top_level_holds_subpackages_and_at_most_eight_modules():
    modules = sorted(p.name for p in SRC.glob("*.py"))
    assert len(modules) <= 8, modules


def test_float64_is_switched_on_in_one_place():
    hits = [p for p in SRC.rglob("*.py") if "jax_enable_x64" in p.read_text(encoding="utf-8")]
    assert [p.relative_to(SRC).as_posix() for p in hits] == ["__init__.py"]


def test_nothing_points_outside_the_repository():
    pattern = re.compile(r"REPRODUCTION\.md|DESIGN\.md|\.\./shared|(?i:\bissues? #?\d+\b)")
    files = [*SRC.rglob("*.py"), *(ROOT / "docs").rglob("*.md"), ROOT / "README.md",
             ROOT / "CHANGELOG.md", ROOT / "mkdocs.yml"]
    hits = [f"{f.relative_to(ROOT)}: {m.group(0)}" for f in files
            for m in pattern.finditer(f.read_text(encoding="utf-8"))]
    assert hits == []


def test_no_test_benchmark_or_default_reads_beside_the_clone():
    """The tests read their data from the repository (tests/data/broad) or make it; benchmarks and
    commands read a dataset where the user says. Nothing reaches for a folder beside the clone
    (a shared data folder named in a path or a string, or a climb above the repository)."""
    pattern = re.compile(r"\.\./shared|shared/dat[a]|[\"']shared[\"']|parents\[[2-9]\]")
    files = [*SRC.rglob("*.py"), *(ROOT / "tests").rglob("*.py"),
             *(ROOT / "benchmarks").rglob("*.py"), *(ROOT / ".ci").iterdir(),
             ROOT / "pyproject.toml"]
    hits = [f"{f.relative_to(ROOT)}: {m.group(0)}" for f in files
            for m in pattern.finditer(f.read_text(encoding="utf-8"))]
    assert hits == []


def _imported_names(module, path, tree) -> set[str]:
    """Every name a module imports, anywhere in it (function-level imports included): the
    modules, and ``module.name`` for each name taken from one."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            src = _resolve(module, path, node)
            names |= {src} | {f"{src}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
    return names


def test_the_tilt_filter_lives_in_one_subpackage():
    """Tilt from an IMU is one subpackage (docs/architecture.md): no tilt module is left in
    ``estimators`` or ``analysis``, and outside ``verticality.tilt`` no module imports the filter's
    internals (core, batch kernel, layout, smoother, plain-Python form): callers use the API."""
    internals = {f"verticality.tilt.{m}" for m in
                 ("core", "kernels", "batch", "layout", "smoother", "stream")}
    assert not [p.name for d in ("estimators", "analysis") for p in (SRC / d).glob("*tilt*")]
    offenders = []
    for module, path, tree in _modules():
        if module == "verticality.tilt" or module.startswith("verticality.tilt."):
            continue
        names = _imported_names(module, path, tree)
        offenders += [f"{module}: {n}" for n in sorted(names & internals)]
    assert offenders == []


def test_gravity_is_written_once():
    # Every model, sensor, estimator and report takes g from core/constants.py, so changing it
    # there changes it everywhere.
    hits = sorted(str(p.relative_to(SRC)) for p in SRC.rglob("*.py")
                  if "9.81" in p.read_text(encoding="utf-8"))
    assert hits == ["core/constants.py"]


def test_experiments_are_leaves():
    """Experiments only run and draw (docs/architecture.md): no module but the CLI, the report and
    the experiments themselves imports ``verticality.experiments``, at module or function level,
    so a closed loop, a model or a metric that two places use lives in the library."""
    allowed = ("verticality.cli", "verticality.report", "verticality.experiments")
    offenders = []
    for module, path, tree in _modules():
        if any(module == a or module.startswith(a + ".") for a in allowed):
            continue
        offenders += [f"{module}: {n}" for n in sorted(_imported_names(module, path, tree))
                      if n == "verticality.experiments" or n.startswith("verticality.experiments.")]
    assert offenders == []
