"""The paper's stack as a policy: formation setpoints → anti-collision → backstepping.

A policy is any callable ``policy(observation) -> action`` for :class:`~swarm_mj.env.SwarmEnv`;
this one returns U1..U4 (n, 4) and is what ``swarm-mj run`` plugs in. :meth:`BacksteppingPolicy.command`
returns the same U with the references and commanded attitude that produced it (a
:class:`~swarm_mj.env.Command`, which ``SwarmEnv.step`` records).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .._jit import bind
from ..env import Command
from ..formation.anticollision import make_rule, resolve_rule
from ..physics.mixing import attitude_priority
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.period import feedforward_force
from ..pipeline.records import Control, Feedforward, Predictor
from ..scenario import Scenario
from .backstepping import Backstepping
from .lag import AttitudePredictor


class DownwashFeedforward:
    """The downwash force (n, 3) each drone is predicted to feel from the jets of the others: the
    simulator's own turbulent-jet model (:class:`swarm_mj.physics.aero.downwash.DownwashStage`, docs/aero.md;
    Bauersfeld et al. 2024 compensate a drone's downwash the same way, from the model), evaluated
    at the drones' positions and attitudes with each drone's last thrust command U1 shared over
    its four rotors. The controller adds it to the external force it already compensates (the
    wind feedforward of eqs. 23–24). Only the force: the jet's torque on a drone half in it is
    left to the attitude loop (taking it off L·U2..L·U4 as predicted made 3 of 8 hard starts worse:
    the prediction lags the drones' attitude by a control period and the rotors' by their lag)."""

    def __init__(self, n: int, params: QuadParams = DEFAULT_PARAMS) -> None:
        from ..physics.aero.downwash import DownwashStage

        self.n = n
        # the simulator's stage for this vehicle (its rotors, body and downwash_gain: the prediction
        # uses the jet the physics flies); its coefficients; the kernel is called directly (one call per step)
        st = DownwashStage.for_vehicle(params)
        self.force = np.zeros((n, 3))  # (n, 3) the last prediction (N)
        self._call: Callable[..., None] | None = None  # feedforward_force bound to the record (_jit.bind)
        z3 = np.zeros((n, 3))
        self._record = Feedforward(
            True, n, float(params.L), st.rho, st.rotor_radius, st.half_cda, st.half_cda_body, np.zeros((n, 3)),
            np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.zeros((n, 4)), self.force, z3, z3.copy(), z3.copy(),
        )  # fmt: skip

    def record(self) -> Feedforward:
        """The feedforward for a compiled driver (swarm_mj.pipeline.records)."""
        return self._record

    def __call__(self, pos: np.ndarray, quat: np.ndarray, thrust: np.ndarray) -> np.ndarray:
        """pos (n, 3), quat (n, 4) (w, x, y, z), thrust (n,) each drone's U1 (N) → force (n, 3) (N)
        (:func:`swarm_mj.pipeline.period.feedforward_force`, the function the compiled driver calls)."""
        c = np.ascontiguousarray  # the inputs as the bound function takes them (the same values)
        args = (self._record, c(pos, dtype=np.float64), c(quat, dtype=np.float64), c(thrust, dtype=np.float64))
        if args[1].shape == (self.n, 3) and args[2].shape == (self.n, 4) and args[3].shape == (self.n,):
            if self._call is None:
                self._call = bind(feedforward_force, *args)
            self._call(*args)
        else:  # the dispatcher types (and checks) them
            feedforward_force(*args)
        return self.force


class BacksteppingPolicy:
    """Backstepping (eqs. 17–24) on formation setpoints adjusted by the anti-collision rule."""

    def __init__(
        self,
        scenario: Scenario,
        params: QuadParams = DEFAULT_PARAMS,
        *,
        gains: np.ndarray | None = None,
        anti_collision: str | None = None,
    ) -> None:
        sc = scenario
        self.n = sc.n_drones
        self.controller = Backstepping(
            self.n,
            sc.gains if gains is None else gains,
            params=params,
            control_period=sc.control_period,
            wind_feedforward=sc.wind_feedforward,
            attitude_map=sc.attitude_map,
        )
        rule_params: dict[str, Any] = {"sensing_range": sc.sensing_range, **sc.anti_collision_params}
        name = resolve_rule(anti_collision, sc.aero.downwash) if anti_collision else sc.rule
        self.rule = make_rule(name, self.n, vehicle=params, barrier=sc.barrier_params, **rule_params)  # its keep-out
        # rotor commands desaturated with attitude priority (ours, docs/interpretations.md §1)
        self.attitude_priority = sc.attitude_priority_on
        # the attitude fed back predicted over the rotors' lag (ours, docs/interpretations.md §2)
        lag = sc.lag_horizons
        self.predictor = None if lag is None else AttitudePredictor(self.n, lag[0], lag[1], sc.control_period)
        # the rule may ask the controller to compensate the downwash, when the physics has one
        self.downwash_ff = (
            DownwashFeedforward(self.n, params)
            if self.n > 1 and self.rule.downwash_feedforward and sc.aero.downwash and sc.wind_feedforward
            else None
        )
        self._ff_started = False
        self._started = False
        self.U_last = np.zeros((self.n, 4))  # (n, 4) the last command, as the compiled command reads it
        # the compiled command's buffers (Control.zeros1, scratch, U_out): no allocation per period
        self._zeros1, self._scratch, self._U_out = np.zeros(self.n), np.zeros((5, self.n, 3)), np.zeros((self.n, 4))
        z3, z4 = np.zeros((self.n, 3)), np.zeros((self.n, 4))
        self._no_ff = Feedforward(False, self.n, 0.0, 0.0, 0.0, 0.0, 0.0, z3, z4, z4, z3, z3, z3, z3)  # stand-in
        self._no_pred = Predictor(False, 0.0, 0.0, np.zeros((self.n, 3)), np.zeros((self.n, 3)))

    def control_record(self) -> Control:
        """The controller for the compiled :func:`swarm_mj.pipeline.period.command` (its own arrays; ``U_last``
        the buffer of the last command)."""
        ctl = self.controller
        p = ctl.params
        prev = ctl._prev_att_d if ctl._prev_att_d is not None else np.zeros((self.n, 2))  # not started yet
        return Control(
            ctl.record, prev, ctl.att_d, self.U_last, ctl.attitude_map == "exact", bool(ctl.wind_feedforward),
            bool(self.attitude_priority), p.unmix_t, p.mix_t, float(p.f_min), float(p.f_max), self._zeros1,
            self._scratch, self._U_out,
        )  # fmt: skip

    def feedforward_record(self) -> Feedforward:
        """The downwash feedforward's record (a stand-in with ``on`` False where there is none)."""
        return self.downwash_ff.record() if self.downwash_ff is not None else self._no_ff

    def predictor_record(self) -> Predictor:
        """The lag prediction's record (a stand-in with ``on`` False where there is none)."""
        return self.predictor.record() if self.predictor is not None else self._no_pred

    def started(self) -> bool:
        """Past the first command: every memory of the controller (the attitude history, the lag
        prediction's last rates, the feedforward's last thrust) holds a value."""
        return (
            self._started
            and self.controller._prev_att_d is not None
            and (self.predictor is None or not self.predictor._first)
            and (self.downwash_ff is None or self._ff_started)
        )

    def reset(self) -> None:
        self.controller.reset()
        if self.predictor is not None:
            self.predictor.reset()
        self._started = False
        self._ff_started = False

    @property
    def events(self) -> list[dict]:
        return self.rule.events

    def command(self, obs: dict) -> Command:
        """U1..U4 (n, 4) for the observation, with the references (n, 3) and attitude (n, 3) behind them."""
        if not self._started:
            self.rule.reset(obs["pos"])
            self._started = True
        pos_d, vel_d, acc_d = obs["setpoint"], obs["setpoint_vel"], obs["setpoint_acc"]
        if self.n > 1:
            # Anti-collision (docs/interpretations.md §4): the rule adjusts the setpoints (n, 3) and,
            # for the drones it steers, also hands the velocity/acceleration references (zero = hold x, y).
            pos_d, vel_d, acc_d = self.rule.references(
                float(obs["time"]), obs["pos"], pos_d, vel_d, acc_d, float(obs["leader_pos"][2])
            )
        ctl = self.controller
        ext = obs["wind_force"]
        if self.downwash_ff is not None:  # the rule's downwash feedforward (docs/interpretations.md §4)
            thrust = ctl.U[:, 0] if self._ff_started else np.full(self.n, ctl.params.m * ctl.params.g)
            ext = ext + self.downwash_ff(obs["pos"], obs["quat"], thrust)
            self._ff_started = True
        rpy, rpy_rate, body_rates = obs["rpy"], obs["rpy_rate"], obs["body_rates"]
        if self.predictor is not None:
            rpy, rpy_rate, body_rates = self.predictor(rpy, rpy_rate, body_rates)
        U = ctl.compute(
            rpy,
            rpy_rate,
            obs["pos"],
            obs["vel"],
            pos_d,
            vel_d,
            acc_d,
            obs["setpoint_yaw"],
            wind_force=ext,
            omega_body=body_rates,
        )
        if self.attitude_priority:
            U = attitude_priority(U, ctl.params.f_min, ctl.params.f_max, ctl.params.unmix_t, ctl.params.mix_t)
            ctl.U = U
        return Command(U, pos_d, vel_d, acc_d, ctl.att_d.copy())

    def __call__(self, obs: dict) -> np.ndarray:
        return self.command(obs).U
