"""The one step pipeline (issue 17): force stages, copies, the health mask with MuJoCo's warnings,
the step record, kernels in their domains, the import graph. Whole runs and other processes (a
divergence's exit 1, cooperative Ctrl-C of issue 16 items 3, 4, the public API in a fresh interpreter):
tests/integration/test_pipeline_runs.py."""

from __future__ import annotations

import ast
from pathlib import Path

import mujoco
import numpy as np
import pytest

from swarm_mj import _jit
from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import Command, StepRecord, SwarmEnv
from swarm_mj.errors import SimulationDiverged
from swarm_mj.physics.mixing import saturate
from swarm_mj.physics.sim import (
    BELOW_FLOOR,
    HEALTHY,
    MUJOCO_WARNING,
    NON_FINITE,
    TILTED,
    DragStage,
    Sim,
    WindStage,
)
from swarm_mj.physics.world import build_world

REPO = Path(__file__).resolve().parents[2]


class ConstantStage:
    """A test stage: a fixed world force (N, 3) and torque (N, 3) on every drone."""

    name = "constant"

    def __init__(self, force, torque=(0.0, 0.0, 0.0)) -> None:
        self.f, self.t = np.asarray(force, float), np.asarray(torque, float)
        self.resets = 0

    def reset(self, sim: Sim) -> None:
        self.resets += 1

    def apply(self, sim: Sim, force: np.ndarray, torque: np.ndarray) -> None:
        force += self.f
        torque += self.t


def _world(n: int = 3, z: float = 2.0, **kw):
    return build_world(n, positions=np.column_stack([2.0 * np.arange(n), np.zeros(n), np.full(n, z)]), **kw)


def _fly(sim: Sim, steps: int, wind=None) -> np.ndarray:
    U = np.tile([sim.params.hover_thrust * 1.01, 0.001, -0.002, 0.0005], (sim.n_total, 1))
    out = []
    for k in range(steps):
        sim.step(U, None if wind is None else wind * (1 + 0.01 * k))
        out.append(np.concatenate([sim.qpos.ravel(), sim.qvel.ravel()]))
    return np.array(out)


# --------------------------------------------------------------------------- force stages


def test_default_stages_are_drag_then_wind_and_the_general_path_is_bit_identical():
    """0 + (−K·v) + F_wind through the stage loop equals the fused −K·v + F_wind, bit for bit."""
    wind = np.array([0.3, -0.2, 0.0])
    fused = Sim(_world())
    assert [s.name for s in fused.stages] == ["drag", "wind"]
    assert isinstance(fused.stages[0], DragStage) and isinstance(fused.stages[1], WindStage)
    general = Sim(_world(), force_stages=[ConstantStage(np.zeros(3))])  # adds exactly zero
    np.testing.assert_array_equal(_fly(fused, 200, wind), _fly(general, 200, wind))


def test_an_extra_force_stage_equals_the_same_force_given_as_wind():
    F = np.array([0.4, -0.1, 0.2])
    as_wind = _fly(Sim(_world()), 100, wind=F)
    stage = ConstantStage(F)
    sim = Sim(_world())
    sim.add_stage(stage)
    assert stage.resets == 1 and [s.name for s in sim.stages] == ["drag", "wind", "constant"]
    U = np.tile([sim.params.hover_thrust * 1.01, 0.001, -0.002, 0.0005], (sim.n_total, 1))
    out = []
    for k in range(100):
        stage.f = F * (1 + 0.01 * k)
        sim.step(U)
        out.append(np.concatenate([sim.qpos.ravel(), sim.qvel.ravel()]))
    np.testing.assert_array_equal(np.array(out), as_wind)
    sim.reset()
    assert stage.resets == 2


def test_a_stage_torque_turns_the_drone_as_euler_says():
    """A world torque τ_z on a drone at rest, gravity balanced, no drag: ω̇_z = τ_z / Iz (independent check)."""
    tau = 2e-3
    world = _world(
        1, params=__import__("swarm_mj.physics.params", fromlist=["QuadParams"]).QuadParams(Kx=0, Ky=0, Kz=0)
    )
    sim = Sim(world, force_stages=[ConstantStage(np.zeros(3), (0.0, 0.0, tau))])
    U = np.array([[world.params.hover_thrust, 0.0, 0.0, 0.0]])
    steps = 10
    for _ in range(steps):
        sim.step(U)
    t = steps * sim.control_period
    assert sim.omega[0, 2] == pytest.approx(tau / world.params.Iz * t, rel=1e-9)
    assert np.abs(sim.omega[0, :2]).max() < 1e-12


def test_swarm_env_takes_extra_force_stages():
    """A stage that adds nothing leaves a swarm run bit-identical (general path == fused path);
    one that pushes moves the swarm."""

    def fly(stages):
        env = SwarmEnv("scenario1", force_stages=stages)
        policy = BacksteppingPolicy(env.scenario, env.params)
        ts = env.reset()
        for _ in range(150):
            ts = env.step(policy.command(ts.observation))
        return ts.observation["pos"]

    plain = fly(())
    np.testing.assert_array_equal(fly([ConstantStage(np.zeros(3))]), plain)
    pushed = fly([ConstantStage(np.array([0.0, 0.0, -1.0]))])  # about 2 m/s² down on every drone
    assert (pushed[:, 2] < plain[:, 2] - 1e-3).all()


# --------------------------------------------------------------------------- copies and health


def test_copies_are_independent_and_the_health_mask_is_per_copy():
    m, n = 3, 2
    sim = Sim(_world(m * n, collisions=False), n_copies=m, max_tilt=np.deg2rad(80))
    assert (sim.n, sim.n_copies, sim.n_total) == (n, m, m * n)
    assert (sim.health() == HEALTHY).all()
    sim.qpos[3, 2] = -1.0  # copy 1, second drone: below the floor
    sim.qvel[4, 0] = np.nan  # copy 2: non-finite
    np.testing.assert_array_equal(sim.health(), [HEALTHY, BELOW_FLOOR, NON_FINITE])
    sim.reset()
    sim.quat[1] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]  # copy 0: rolled 90°
    np.testing.assert_array_equal(sim.health(), [TILTED, HEALTHY, HEALTHY])


def test_parked_copies_hold_their_start_and_the_others_fly_as_alone():
    m = 3
    alone = Sim(_world(1, collisions=False))
    batched = Sim(build_world(m, positions=np.tile([0.0, 0.0, 2.0], (m, 1)), collisions=False), n_copies=m)
    U1 = np.array([[alone.params.hover_thrust * 1.05, 0.001, 0.0, 0.0]])
    for k in range(50):
        if k == 10:
            batched.park([1])
        batched.step(np.tile(U1, (m, 1)))
        alone.step(U1)
    np.testing.assert_array_equal(batched.qpos[0], alone.qpos[0])
    np.testing.assert_array_equal(batched.qpos[2], alone.qpos[0])
    np.testing.assert_array_equal(batched.pos[1], [0.0, 0.0, 2.0])  # put back before every step
    assert (batched.health() == HEALTHY).all()


def test_a_mujoco_divergence_warning_is_a_divergence_even_when_the_state_looks_sane():
    """A huge force makes MuJoCo reset the data (mjWARN_BADQACC): the state is back at rest, finite."""
    sim = Sim(_world(2))
    sim.step(np.zeros((2, 4)), np.array([1e12, 0.0, 0.0]))
    assert sim.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
    assert np.isfinite(sim.qpos).all()
    assert (sim.health() == MUJOCO_WARNING).all()
    with pytest.raises(SimulationDiverged, match="mjWARN_BADQACC"):
        sim.check()
    sim.reset()
    assert (sim.health() == HEALTHY).all()


# --------------------------------------------------------------------------- the step record


def test_step_record_holds_what_was_applied_and_why():
    env = SwarmEnv("scenario1")
    policy = BacksteppingPolicy(env.scenario, env.params)
    ts = env.reset()
    assert env.last_applied is None
    for k in range(30):
        cmd = policy.command(ts.observation)
        assert isinstance(cmd, Command)
        ts = env.step(cmd)
        rec = env.last_applied
        assert isinstance(rec, StepRecord)
        assert rec.time == pytest.approx(k * env.T)
        U, F = saturate(cmd.U, env.params.f_min, env.params.f_max)
        np.testing.assert_array_equal(rec.U, U)
        np.testing.assert_array_equal(rec.rotor_thrust, F)
        np.testing.assert_array_equal(rec.U, env.sim.ctrl)
        np.testing.assert_array_equal(rec.wind_force, env.wind.drone_forces(k, np.zeros((env.n, 3))))
        assert rec.pos_d is cmd.pos_d and rec.att_d is cmd.att_d
    ts = env.step(np.asarray(policy(ts.observation)))  # a plain U: no references
    assert env.last_applied.pos_d is None and env.last_applied.att_d is None


def test_setpoint_actions_record_their_references_and_attitude():
    env = SwarmEnv("circle", action="setpoint")
    ts = env.reset()
    target = ts.observation["pos"] + np.array([0.0, 0.0, 1.0])
    env.step(target)
    rec = env.last_applied
    np.testing.assert_array_equal(rec.pos_d, target)
    assert (rec.vel_d == 0).all() and (rec.acc_d == 0).all()
    np.testing.assert_array_equal(rec.att_d, env._setpoint_ctl.att_d)


# --------------------------------------------------------------------------- kernels, imports, API


def test_warm_up_compiles_every_registered_kernel():
    _jit.warm_up(everything=True)  # what `swarm-mj warm-up` does
    assert len(_jit.REGISTRY) >= 15
    assert {"swarm_mj.formation.barrier_filter.barrier_step", "swarm_mj.task.observe_copies"} <= _jit.ON_DEMAND
    if not _jit.AVAILABLE:
        pytest.skip("numba not in use: kernels run as numpy")
    for name, (kernel, samples) in _jit.REGISTRY.items():
        if samples is not None:
            assert kernel.signatures, name


def test_a_runs_warm_up_leaves_on_demand_kernels_to_their_owner():
    """_jit.jit(on_demand=True): a run's warm_up does not compile it (a first run compiles only what
    every run needs); warm_module, which the owner calls when it is built, does."""
    if not _jit.AVAILABLE:
        pytest.skip("numba not in use: kernels run as numpy")

    def _probe_on_demand(x):
        return x + 1.0

    _probe_on_demand.__module__ = "_probe_on_demand_module"
    _probe_on_demand.__qualname__ = "_probe_on_demand"
    kernel = _jit.jit(on_demand=True, samples=lambda: [(1.0,)])(_probe_on_demand)
    name = "_probe_on_demand_module._probe_on_demand"
    try:
        assert name in _jit.ON_DEMAND and name not in _jit.uncached()
        _jit.warm_up()
        assert not kernel.signatures
        _jit.warm_module("_probe_on_demand_module")
        assert kernel.signatures
    finally:
        _jit.REGISTRY.pop(name, None)
        _jit.ON_DEMAND.discard(name)


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module imported, names) of every import in a swarm_mj source file, resolved to absolute names."""
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append((mod, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
    return out


def test_no_import_cycles_and_no_private_names_across_modules():
    files = sorted((REPO / "swarm_mj").rglob("*.py"))
    modules = {".".join(f.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__"): f for f in files}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    private = []
    for mod, f in modules.items():
        for target, names in _imports(f):
            if not target.startswith("swarm_mj"):
                continue
            for name in names:
                if f"{target}.{name}" in modules:  # a submodule
                    graph[mod].add(f"{target}.{name}")
                elif name.startswith("_") and not name.startswith("__"):
                    private.append(f"{mod}: {target}.{name}")
            if target in modules and target != mod:
                graph[mod].add(target)
    assert not private, private
    # a package's __init__ re-exporting its modules is not a cycle of the code; the modules themselves must be acyclic
    code = {
        m: {t for t in deps if not (m.startswith(t + ".") and t in modules and modules[t].name == "__init__.py")}
        for m, deps in graph.items()
    }
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(m: str, stack: list[str]) -> bool:
        state[m] = 1
        for t in sorted(code.get(m, ())):
            if state.get(t) == 1:
                cycle.extend(stack[stack.index(t) :] + [t] if t in stack else [m, t])
                return True
            if state.get(t) is None and visit(t, stack + [t]):
                return True
        state[m] = 2
        return False

    for m in sorted(code):
        if state.get(m) is None and visit(m, [m]):
            break
    assert not cycle, " -> ".join(cycle)


#: NamedTuple's public API, spelled with an underscore so as not to clash with field names
_NAMEDTUPLE_API = frozenset({"_replace", "_asdict", "_fields", "_field_defaults", "_make"})


def _private_reads(source: str) -> list[str]:
    """Every attribute access ``X._name`` in ``source`` where X is not ``self`` or ``cls`` (dunder names and
    NamedTuple's ``_replace``/``_asdict``/... allowed), as "line: X._name"."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Attribute):
            continue
        name = node.attr
        if not name.startswith("_") or (name.startswith("__") and name.endswith("__")) or name in _NAMEDTUPLE_API:
            continue
        if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
            continue
        out.append(f"{node.lineno}: {ast.unparse(node)}")
    return out


def test_the_pipeline_reads_no_private_attribute_of_another_object():
    """swarm_mj/pipeline/ talks to the environment, the simulator and Numba through their public
    interfaces (``SwarmEnv.after_chunk``, ``Sim.pairs_in_contact``, ``swarm_mj._jit.cached_signatures``...),
    never through their private attributes."""
    found = {
        f.name: hits
        for f in sorted((REPO / "swarm_mj" / "pipeline").glob("*.py"))
        if (hits := _private_reads(f.read_text()))
    }
    assert found == {}, found


def test_the_private_attribute_check_finds_one_where_there_is_one():
    src = "def f(env, self):\n    a = env._obs\n    env.sim._pairs = 1\n    b = self._x, o._replace(x=1), o.__class__\n"
    assert _private_reads(src) == ["2: env._obs", "3: env.sim._pairs"]


def test_no_function_of_the_package_takes_more_than_20_parameters():
    """State lives in typed records, not in argument lists of dozens (docs/design.md, "The control
    period, written once"): tools/max_params.py over swarm_mj/ finds nothing (the next test shows
    that it finds one where there is one)."""
    import importlib.util as _util

    spec = _util.spec_from_file_location("max_params", REPO / "tools" / "max_params.py")
    assert spec is not None and spec.loader is not None
    mod = _util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.too_many(REPO / "swarm_mj", 20) == []


def test_the_parameter_check_counts_a_long_signature(tmp_path):
    import importlib.util as _util

    spec = _util.spec_from_file_location("max_params", REPO / "tools" / "max_params.py")
    assert spec is not None and spec.loader is not None
    mod = _util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    (tmp_path / "m.py").write_text("def f(" + ", ".join(f"a{i}" for i in range(21)) + ", *, b=1): pass\n")
    assert [(name, n) for _, _, name, n in mod.too_many(tmp_path, 20)] == [("f", 22)]
