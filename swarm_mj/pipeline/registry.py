"""Every stage of a control period that has a compiled step, and every named anti-collision rule: the one
registry (docs/design.md, "The control period, written once").

Registration is one line here, never a side effect of importing a stage's module: whoever looks a kernel
up (the simulator's unrolled stage and monitor tuples, the chunk driver's check, the background compile
process started by :func:`swarm_mj.pipeline.fast.compile_in_background`) imports this module, and this
module imports every module it names, so a fresh interpreter sees every kernel whichever module it
imported first.

* :data:`FORCE_KERNELS`: a force stage's record type (what its ``record()`` returns) → its compiled
  ``apply(record, kinematics, force, torque)``, which ADDS the stage's world-frame force and torque (N, 3)
  for the coming physics step and writes its own into ``record.force``;
* :data:`MONITOR_KERNELS`: a monitor's record type → its compiled ``after_step(record, kinematics)``, what
  it does after a physics step without any contact (a contact always goes back to its Python);
* :data:`RULE_KERNELS`: a rule's record type → its compiled ``step(record, obs, t) -> (react, pos_d, vel_d,
  acc_d)``, what the chunk driver calls each period (:func:`swarm_mj.pipeline.period.fly_chunk`, through its
  ``_rule_period``, chosen by the record's type when the driver is compiled): ``obs`` the period's
  :class:`~swarm_mj.pipeline.records.Obs` (positions, slots ``sp`` and their references ``spv``, ``spa``
  (n, 3)), ``t`` (s); returns the controller's references (n, 3), or react True to hand the period back to
  Python (the rule's ``update`` flies it: the layered rule's Fig. 5). The rule's Python ``update`` calls the
  same compiled function, so both drivers give the same numbers. A record with the fields a separation
  filter reads (``vel``, ``prev_t``, ``steer``: the layered rule's) has its filter run after the step;
  another rule flies without one (the driver passes the filter switched off);
* :data:`FILTER_KERNELS`: a separation filter's record type → its compiled period;
* :data:`RULE_CHECKS`: a rule's record type → its compiled ``check(record, obs)``: the step would hand the
  period back (under a sensing model every drone's copy of the rule is asked before any steps);
* :data:`SENSING_KERNELS`: a sensing stage's record type → its compiled tick;
* :data:`ANTI_COLLISION_RULES`: a rule's name (a scenario's ``formation.anti_collision``) → its class.

Whether a run flies on the chunk driver is decided by capability: every force stage, monitor, the rule
and its separation filter return from ``record()`` a record type this registry holds
(:func:`why_not_compiled`). A stage outside the package registers the same way, one line where its user
builds it (``registry.FORCE_KERNELS[MyRecord] = my_apply``); its kernel's module must also be in
:data:`swarm_mj._jit.KERNEL_MODULES` (the chunk driver's cache is checked against those sources), and
importable by every later process on the machine (an installed module, not a script): the chunk
driver's on-disk cache then holds a signature with its record type, and Numba's index of that cache
cannot be read where the module cannot be imported.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .. import _jit
from ..formation.barrier import BarrierPlannerRule, BarrierRecord, barrier_step
from ..formation.jet_aware import JetAwareRule
from ..formation.layered import formed_check, formed_step
from ..formation.planner import LayeredRule
from ..formation.rules import NoRule, PaperRule, Rule
from ..formation.stagger import StaggerRecord, StaggerRule, stagger_step
from ..physics.aero.downwash import DownwashRecord, downwash_apply
from ..physics.aero.ground import ground_track
from ..physics.aero.ground_effect import GroundEffectRecord, ground_effect_apply
from ..physics.aero.updraft import UpdraftRecord, updraft_apply
from ..sensing.stage import SenseRecord, sense_step
from .records import GroundTrack
from .records import Rule as FormedRecord

#: force stage record → compiled ``apply(record, kinematics, force, torque)``
FORCE_KERNELS: dict[type, Callable[..., Any]] = {
    DownwashRecord: downwash_apply,
    GroundEffectRecord: ground_effect_apply,
    UpdraftRecord: updraft_apply,
}

#: monitor record → compiled ``after_step(record, kinematics)`` (a physics step without any contact)
MONITOR_KERNELS: dict[type, Callable[..., Any]] = {
    GroundTrack: ground_track,
}

#: rule record → its compiled ``step(record, obs, t) -> (react, pos_d, vel_d, acc_d)`` (the contract above)
RULE_KERNELS: dict[type, Callable[..., Any]] = {
    FormedRecord: formed_step,
    StaggerRecord: stagger_step,  # the worked example of docs/design.md, "A new rule"
}

#: the fields of a rule's record a separation filter reads after the rule's step (the layered rule's record
#: has them: the estimated velocities, the time of the last update, the steered drones)
FILTER_READS = ("vel", "prev_t", "steer")

#: separation filter record → its compiled period (swarm_mj.pipeline.period.fly_chunk calls it after the rule)
FILTER_KERNELS: dict[type, Callable[..., Any]] = {
    BarrierRecord: barrier_step,
}

#: rule record → its compiled ``check(record, obs) -> bool``: its step would hand this period back, changing
#: nothing (a rule flown from each drone's own view asks every copy before any steps: a rule without one flies
#: such runs step by step)
RULE_CHECKS: dict[type, Callable[..., Any]] = {
    FormedRecord: formed_check,
}

#: sensing stage record → its compiled tick (swarm_mj.sensing.stage; the perfect oracle has no stage)
SENSING_KERNELS: dict[type, Callable[..., Any]] = {
    SenseRecord: sense_step,
}

#: the named anti-collision rules, in the order the CLI lists them (``"auto"`` picks one: anticollision.AUTO)
ANTI_COLLISION_RULES: dict[str, type[Rule]] = {
    "layers": LayeredRule,
    "paper": PaperRule,
    "off": NoRule,
    "jet-aware": JetAwareRule,
    "barrier": BarrierPlannerRule,
    "stagger": StaggerRule,
}


def why_not_compiled(part: Any, table: dict[type, Callable[..., Any]], kind: str, what: str) -> str | None:
    """Why ``part`` (a force stage, monitor, rule or separation filter) cannot fly in a compiled driver
    (None: it can): it has no ``record()`` whose type ``table`` holds, or that kernel's module is not in
    :data:`swarm_mj._jit.KERNEL_MODULES` (then a change to it would not invalidate the driver's cache).
    ``kind``, ``what``: the words of the reason (``"force stage"``, ``"kernel"``)."""
    name = getattr(part, "name", type(part).__name__)
    make = getattr(part, "record", None)
    kernel = table.get(type(make())) if callable(make) else None
    if kernel is None:
        return f"the {kind} {name!r} has no compiled {what}"
    module = getattr(getattr(kernel, "py_func", kernel), "__module__", "")
    if module not in _jit.KERNEL_MODULES:
        return f"the {kind} {name!r}: its compiled {what}'s module {module} is not in _jit.KERNEL_MODULES"
    return None


__all__ = [
    "ANTI_COLLISION_RULES",
    "FILTER_KERNELS",
    "FILTER_READS",
    "FORCE_KERNELS",
    "MONITOR_KERNELS",
    "RULE_CHECKS",
    "RULE_KERNELS",
    "SENSING_KERNELS",
    "why_not_compiled",
]
