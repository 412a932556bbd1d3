"""The physics of a control period over the records, compiled (docs/design.md, "the step pipeline"): saturation
and the floor gate (:func:`hold_inputs`), then the physics steps (:func:`physics_steps`: each step's forces,
:func:`apply_forces`, MuJoCo's ``mj_step``, the compiled monitors), and the health test (:func:`unhealthy`).
:meth:`swarm_mj.physics.sim.Sim.step` flies a period with :func:`period_physics`; the chunk driver
(swarm_mj/pipeline/period.py) calls the same functions. The force stages and monitors are tuples of records,
each record's compiled step found in :mod:`swarm_mj.pipeline.registry` and unrolled at compile time.
"""

from __future__ import annotations

from .._jit import AVAILABLE, jit
from ..pipeline import registry
from ..pipeline.records import Kinematics
from . import _mjstep
from .kernels import (
    DIVERGENCE_WARNING_IDS,
    drag_kernel,
    first_unhealthy,
    floor_gate_kernel,
    flush_stage_forces,
    unmix_kernel,
)
from .mixing import saturate_kernel


def _apply_stages(stages, kin, force, torque):  # pragma: no cover - replaced by the overload when compiled
    """Each compiled stage of the tuple ``stages`` (records) adds its force and torque (N, 3)."""
    for rec in stages:
        registry.FORCE_KERNELS[type(rec)](rec, kin, force, torque)


def _apply_stages_compiled(stages, kin, force, torque):
    """The stage tuple unrolled at compile time: each record's registered kernel in turn."""
    kernels = [registry.FORCE_KERNELS[t.instance_class] for t in stages.types]
    body = "".join(f"    k{i}(stages[{i}], kin, force, torque)\n" for i in range(len(kernels)))
    src = "def impl(stages, kin, force, torque):\n" + body + "    return None\n"
    scope = {f"k{i}": k for i, k in enumerate(kernels)}
    exec(src, scope)  # noqa: S102 - source built from the registry above, no outside text
    return scope["impl"]


def _log_stages(stages, rows, k):  # pragma: no cover - replaced by the overload when compiled
    for j, rec in enumerate(stages):
        rows[j, k] = rec.force


def _log_stages_compiled(stages, rows, k):
    """rows[j, k] (S, K+1, N, 3) = the j-th stage's force of the last physics step."""
    body = "".join(f"    rows[{j}, k] = stages[{j}].force\n" for j in range(len(stages.types)))
    src = "def impl(stages, rows, k):\n" + body + "    return None\n"
    scope: dict = {}
    exec(src, scope)  # noqa: S102
    return scope["impl"]


def _track_monitors(monitors, kin):  # pragma: no cover - replaced by the overload when compiled
    for rec in monitors:
        registry.MONITOR_KERNELS[type(rec)](rec, kin)


def _track_monitors_compiled(monitors, kin):
    """The monitor tuple unrolled at compile time: each record's registered step in turn."""
    kernels = [registry.MONITOR_KERNELS[t.instance_class] for t in monitors.types]
    body = "".join(f"    k{i}(monitors[{i}], kin)\n" for i in range(len(kernels)))
    scope = {f"k{i}": k for i, k in enumerate(kernels)}
    exec("def impl(monitors, kin):\n" + body + "    return None\n", scope)  # noqa: S102
    return scope["impl"]


if AVAILABLE:  # the tuples unrolled when compiled; the Python fallbacks above run as they are otherwise
    from numba.extending import overload

    overload(_apply_stages)(_apply_stages_compiled)
    overload(_log_stages)(_log_stages_compiled)
    overload(_track_monitors)(_track_monitors_compiled)


@jit(inline=True)
def track_monitors(monitors, kin) -> None:
    """Each compiled monitor's step after a physics step without any contact (registry.MONITOR_KERNELS)."""
    _track_monitors(monitors, kin)


@jit(inline=True)
def apply_forces(phys, stages, kin, xf, xtorque) -> None:
    """One physics step's forces into xfrc_applied (xf, xtorque (N, 3) views): drag −K·v + the wind
    held over the period (eq. 1, eq. 37), the produced rotor thrusts of lagged rotors, then each
    compiled force stage's force and torque (their sum added, the torque set; the sums zeroed)."""
    drag_kernel(kin.vel, phys.neg_drag, phys.wind, xf)
    if phys.lag:
        unmix_kernel(phys.act, phys.unmix_t, phys.rotor_thrust)
    if len(stages) > 0:
        _apply_stages(stages, kin, phys.force, phys.torque)
        flush_stage_forces(xf, xtorque, phys.force, phys.torque)


@jit(inline=True)
def log_stage_forces(stages, rows, k) -> None:
    """The force (N, 3) of each stage of ``stages`` into rows[j, k] (S, K+1, N, 3)."""
    _log_stages(stages, rows, k)


@jit(inline=True)
def hold_inputs(phys, U) -> None:
    """Saturation (docs/interpretations.md §1): U (n, 4) → rotor thrusts clipped to [f_min, f_max] →
    ``ctrl``, held over the period; the rotors' command where they lag; the floor gate."""
    saturate_kernel(U, phys.unmix_t, phys.mix_t, phys.f_min, phys.f_max, phys.ctrl, phys.rotor_thrust)
    if phys.lag:
        for i in range(phys.rotor_command.shape[0]):  # a loop: a slice copy costs seconds of compiling
            for r in range(4):
                phys.rotor_command[i, r] = phys.rotor_thrust[i, r]
    if phys.gate_on:
        floor_gate_kernel(phys.qpos, phys.qvel, phys.gate_z, phys.T, phys.contype, phys.gate_id, phys.gate_solid)


@jit(inline=True)
def unhealthy(phys) -> bool:
    """Sim.check's test: a MuJoCo divergence warning, or a state :func:`first_unhealthy` flags."""
    for w in DIVERGENCE_WARNING_IDS:
        if phys.warn[w]:
            return True
    n = phys.qpos.shape[0]
    return first_unhealthy(phys.qpos, phys.qvel, n, 1, phys.floor_z, phys.max_distance, phys.max_tilt) != 0


@jit(inline=True)
def physics_steps(phys, stages, monitors, kin, xf, xtorque, s0, python_each) -> int:
    """The physics steps s0 .. nsub − 1 of a control period (2. of the module docstring): each step's forces
    (:func:`apply_forces`), MuJoCo's own ``mj_step`` (:func:`swarm_mj.physics._mjstep.step_call`), then the
    compiled monitors (:func:`track_monitors`). Returns 0 when the period's steps are done, else the
    number of the next step (1 .. nsub) after the step that hands back to Python: one with a contact
    (``ncon`` > 0: :meth:`Sim.after_physics_step` counts it), or every step when ``python_each`` (Python
    still holds drones in contact, or a monitor's Python must see each step). Needs a compiled
    ``mj_step`` (:func:`swarm_mj.physics._mjstep.available`). The chunk driver's physics
    (swarm_mj/pipeline/period.py) and :meth:`Sim.step`'s (through :func:`period_physics`)."""
    for s in range(s0, phys.nsub):
        apply_forces(phys, stages, kin, xf, xtorque)
        _mjstep.step_call(phys.fn, phys.m_addr, phys.d_addr)  # type: ignore[call-arg]  # a Numba intrinsic
        if phys.ncon[0] > 0 or python_each:
            return s + 1
        track_monitors(monitors, kin)
    return 0


@jit(inline=True)
def drone_views(phys):
    """The views of the drones' rows a physics step reads and writes: (kinematics, xfrc force (N, 3),
    xfrc torque (N, 3)), the drones' bodies at body0 + i·body_step of ``phys.xfrc``."""
    n = phys.qpos.shape[0]
    rows = phys.xfrc[phys.body0 : phys.body0 + n * phys.body_step : phys.body_step]
    kin = Kinematics(
        pos=phys.qpos[:, 0:3], quat=phys.qpos[:, 3:7], vel=phys.qvel[:, 0:3], rotor_thrust=phys.rotor_thrust
    )
    return kin, rows[:, 0:3], rows[:, 3:6]


@jit
def period_physics(phys, stages, monitors, U, s0, python_each) -> int:
    """:meth:`Sim.step`'s one compiled call per control period: from its start (``s0`` = 0) saturation
    and the floor gate (:func:`hold_inputs`, U (N, 4)), then :func:`physics_steps` from step ``s0``; returns
    what :func:`physics_steps` returns (0: the period is flown; s > 0: Python handles step s − 1's contacts
    and monitors, then calls again with ``s0`` = s unless s = nsub). The chunk driver calls the same two
    stage functions (swarm_mj/pipeline/period.py, ``fly_chunk``)."""
    if s0 == 0:
        hold_inputs(phys, U)
    kin, xf, xtorque = drone_views(phys)
    return physics_steps(phys, stages, monitors, kin, xf, xtorque, s0, python_each)
