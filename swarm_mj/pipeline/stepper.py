"""The step-by-step control period: :func:`swarm_mj.pipeline.period.fly_chunk`'s Python body, one period a
call (docs/design.md, "The control period, written once").

The chunk driver calls :func:`~swarm_mj.pipeline.period.fly_chunk` compiled, for up to ``CHUNK`` periods a
call. Every other period runs the same function's body in Python (:func:`swarm_mj._jit.python_body`), with
the stages below in place of its compiled ones: the owners' Python objects, which also run where no compiled
step exists (a rule without one, a force stage or monitor in Python, no Numba). Its other callees run compiled.

* :class:`GivenPeriod`, :meth:`swarm_mj.env.SwarmEnv.step` and :meth:`swarm_mj.wrappers.vector.SwarmVectorEnv.step`:
  the action given (U, a :class:`~swarm_mj.env.Command`, the setpoint controller's U) is the period's command;
  nothing is logged.
* :class:`StepPeriod`, a run's periods the chunk driver does not fly (before it is ready, after Fig. 5 acted,
  every period of a run that cannot fly it): the built-in policy decides, the run's log takes the rows.

======================================  ===================================================================
stage of ``fly_chunk``                  :class:`GivenPeriod` / :class:`StepPeriod`
======================================  ===================================================================
``_period_rules``                       the action's references / the policy's ``references`` (the rule in
                                        Python: Fig. 5 reacts here; under a sensing model each drone's copy
                                        on its own view)
``_period_inputs``                      the observation / the policy's ``inputs`` (each drone's own estimates
                                        and feedforward)
``command``                             the action's U / the policy's ``finish`` (``period.command``'s body)
``log_inputs``, ``_period_view_log``    nothing / ``period.log_inputs``' Python body on the run log's rows,
                                        the view log's row
``hold_wind``, ``hold_inputs``,         the owner's physics (:meth:`~swarm_mj.env.SwarmEnv.fly`: the wind
``drone_views``, ``physics_steps``      held, uniform or on the airspeed; ``Sim.step``, its contacts and
                                        monitors counted; k + 1)
``log_outputs``                         nothing / ``RunLog.applied`` (what the simulator applied)
``unhealthy``                           what the owner's physics returned (the vector env: never, each copy's
                                        health is the task's)
``observe_into``, ``_period_sense``     the owner's observation (:meth:`~swarm_mj.env.SwarmEnv.observe_next`:
                                        its sensing stage ticks)
======================================  ===================================================================

A period so flown never hands back :data:`~swarm_mj.pipeline.period.REACT` (the Python rule reacts in it) nor
:data:`~swarm_mj.pipeline.period.CONTACT` (``Sim.step`` counts each contact).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .._jit import python_body
from ..errors import UserError
from . import period as _period


class _Given(NamedTuple):
    """What the period reads of the controller where the command is given: the command it holds, the attitude."""

    U_last: np.ndarray  # (n, 4)
    att_d: np.ndarray  # (n, 3)


class Clock(NamedTuple):
    """What the period reads of the simulator where its owner flies the physics: the control period T."""

    T: float
    qpos: None = None
    qvel: None = None


class NoRefs(NamedTuple):
    """What the period reads of the references where no stage logs them: rows of zeros (one, for k = 0)."""

    wind_speed: np.ndarray = np.zeros((1, 3))
    D: np.ndarray = np.zeros(1)


class GivenPeriod:
    """The period with its command given (module docstring): :meth:`fly` flies it with U. ``fly(U, refs)``
    flies the owner's physics (returns whether it is healthy after it), ``observe()`` takes its next
    observation; ``n`` rows of U, control period ``T``. :meth:`swarm_mj.env.SwarmEnv.step` (one swarm) and
    :meth:`swarm_mj.wrappers.vector.SwarmVectorEnv.step` (m copies, each healthy or not on its own) fly it."""

    def __init__(self, n: int, T: float, fly: Callable[..., bool], observe: Callable[[], Any]) -> None:
        self._fly, self._observe_next = fly, observe
        self._U: Any = None  # the period's command (n, 4)
        self._refs: tuple | None = None  # (pos_d, vel_d, acc_d, att_d) behind it, or None
        self._healthy = True
        self._flying = True
        self._given = _Given(U_last=np.zeros((n, 4)), att_d=np.zeros((n, 3)))
        self._clock, self._no_refs = Clock(T=float(T)), NoRefs()
        self._body = python_body(_period.fly_chunk, self.stages())

    def stages(self) -> dict[str, Any]:
        """The Python stages of the period (module docstring's table), by the name ``fly_chunk`` calls."""
        return {
            "_period_rules": _no_references,
            "_period_inputs": _as_observed,
            "command": self._command,
            "all_finite": _period.all_finite,  # (typed at each call: a given command has any layout)
            "log_inputs": nothing,
            "_period_view_log": nothing,
            "drone_views": no_views,
            "hold_wind": nothing,  # (the owner's physics holds the wind, uniform or on the airspeed)
            "hold_inputs": nothing,  # (and saturates the command)
            "physics_steps": self._physics,
            "log_outputs": nothing,
            "unhealthy": self._unhealthy,
            "observe_into": self._observe,
            "_period_sense": nothing,  # (the observation ticks the sensing stage)
        }

    def fly(self, U: np.ndarray, refs: tuple | None = None) -> int:
        """Fly the period with U (n, 4), finite, and the references behind it (what the owner's ``fly``
        records); returns the period's status: :data:`~swarm_mj.pipeline.period.DONE` (observed) or
        :data:`~swarm_mj.pipeline.period.UNHEALTHY` (not observed)."""
        self._U, self._refs = U, refs
        return self._run(0, self._clock, self._no_refs, None, self._given, None)

    def _run(self, k: int, phys: Any, refs: Any, obs: Any, ctl: Any, log: Any) -> int:
        status, _, _ = self._body(
            k, 0, k + 1, False, phys, refs, obs, None, None, None, ctl, None, None, log, None, None
        )
        if status == _period.BAD_ACTION:
            raise UserError("action contains NaN or inf")
        if status not in (_period.DONE, _period.UNHEALTHY):
            raise AssertionError(f"internal: a step-by-step period handed back status {status}")
        return status

    # ------------------------------------------------------------------ stages
    def _command(self, ctl, known, pred, seen, pos_d, vel_d, acc_d, first):  # noqa: ANN001, ANN202, ARG002
        return self._U

    def _physics(self, phys, stages, monitors, kin, xf, xtorque, s0, python_each) -> int:  # noqa: ANN001, ARG002
        if self._flying:
            self._healthy = self._fly(self._U, self._refs)
        return 0

    def _unhealthy(self, phys) -> bool:  # noqa: ANN001, ARG002
        return not self._healthy

    def _observe(self, qpos, qvel, T, refs, obs, k) -> None:  # noqa: ANN001, ARG002
        if self._flying:
            self._observe_next()


class StepPeriod(GivenPeriod):
    """One run's step-by-step period (module docstring): :meth:`fly_next` flies period ``env.k`` of the built-in
    policy, its rows into the run's log; :meth:`sample` is the run's last sample. ``env``: a
    :class:`~swarm_mj.env.SwarmEnv` after its reset; ``policy``: a
    :class:`~swarm_mj.control.policy.BacksteppingPolicy`; ``log``: a :class:`~swarm_mj.experiments.runner.RunLog`."""

    def __init__(self, env, policy, log) -> None:  # noqa: ANN001 - SwarmEnv, BacksteppingPolicy, RunLog
        self.env, self.policy, self.log = env, policy, log
        super().__init__(env.n, env.T, env.fly, env.observe_next)

    def stages(self) -> dict[str, Any]:
        stages = {
            **super().stages(),
            "_period_rules": self._rules,
            "_period_inputs": self._inputs,
            "log_inputs": python_body(_period.log_inputs),  # (compiled for Python callers: seconds)
            "_period_view_log": self._view_row,
            "log_outputs": self._applied,
        }
        del stages["all_finite"]  # compiled, bound at the first call: the policy's U is (n, 4), C-ordered
        return stages

    def fly_next(self) -> dict:
        """Fly the period ``env.k``; returns the next observation. Raises
        :class:`~swarm_mj.errors.SimulationDiverged` (naming why) where the simulator is unhealthy after it,
        and :class:`~swarm_mj.errors.UserError` for a non-finite command (nothing applied)."""
        if self._run_next() == _period.UNHEALTHY:
            self.env.sim.check()  # raises SimulationDiverged, naming why
            raise AssertionError("internal: a period the simulator calls healthy was flagged")
        return self.env.observation

    def sample(self) -> None:
        """The run's last sample, ``env.k``: the period's stages up to its log rows (the references, the
        command from them, the input rows), with nothing flown (its outputs hold the last period's:
        ``RunLog.hold_last``)."""
        self._flying = False
        try:
            self._run_next()
        finally:
            self._flying = True

    def _run_next(self) -> int:
        env = self.env
        return self._run(env.k, env.sim.record(), env.refs, env.obs_record, self.policy.control_record(), self.log.rows)

    # ------------------------------------------------------------------ stages
    def _rules(self, rules, filts, view, obs, t):  # noqa: ANN001, ANN202, ARG002
        return (False, *self.policy.references(self.env.observation))

    def _inputs(self, ff, view, obs, k, ctl):  # noqa: ANN001, ANN202, ARG002
        return self.policy.inputs(self.env.observation)

    def _command(self, ctl, known, pred, seen, pos_d, vel_d, acc_d, first):  # noqa: ANN001, ANN202, ARG002
        cmd = self.policy.finish(seen, pos_d, vel_d, acc_d, known)
        self._U, self._refs = cmd.U, (cmd.pos_d, cmd.vel_d, cmd.acc_d, cmd.att_d)
        return cmd.U

    def _view_row(self, view, k) -> None:  # noqa: ANN001, ARG002
        views, sensing = self.log.views, self.env.sensing
        if views is not None and sensing is not None:
            views.record(k, sensing)

    def _applied(self, log, k, phys, stages) -> None:  # noqa: ANN001, ARG002
        if self._flying:
            self.log.applied(k, self.env.sim)


def _no_references(rules, filts, view, obs, t):  # noqa: ANN001, ANN202, ARG001
    """The rule's stage where the action is given: nothing to decide."""
    return False, None, None, None


def _as_observed(ff, view, obs, k, ctl):  # noqa: ANN001, ANN202, ARG001
    """The inputs' stage where the action is given: the observation, no feedforward."""
    return obs, None


def no_views(phys):  # noqa: ANN001, ANN201, ARG001
    """The ``drone_views`` stage where the owner flies the physics: no rows for the compiled physics."""
    return None, None, None


def nothing(*args: Any) -> None:  # noqa: ARG001
    """A stage the owner does elsewhere, or not at all (module docstring)."""
