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

from .._jit import Bound, bind, python_body
from ..env import Command
from ..formation.anticollision import make_rule, resolve_rule
from ..formation.barrier import BarrierFilter
from ..formation.own_view import OwnViewRule
from ..formation.rules import Rule
from ..formation.slots import min_slot_spacing
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.period import command, feedforward_force, viewed_feedforward
from ..pipeline.records import Control, Feedforward, Obs, Predictor
from ..scenario import Scenario
from ..sensing.channel import channel_config
from ..sensing.margin import BarrierMargin, barrier_margin
from ..sensing.payload import PayloadRecord, payload_record
from ..sensing.stage import sensing_stage
from .backstepping import Backstepping
from .lag import AttitudePredictor

_F8 = np.dtype(np.float64)


def _f8(a: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` as a writeable C-ordered float64 array of ``shape`` (itself when it is one, else a copy; a
    smaller array is broadcast): what the bound kernels take (the invariant of :func:`swarm_mj._jit.bind`)."""
    b = np.ascontiguousarray(a, dtype=_F8)
    if b.shape == shape and b.flags.writeable:
        return b
    return np.array(np.broadcast_to(b, shape), dtype=_F8, order="C")


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
            on=True,
            n=n,
            L=float(params.L),
            dirs=params.rotor_dirs,
            rho=st.rho,
            r=st.rotor_radius,
            half_cda=st.half_cda,
            half_cda_body=st.half_cda_body,
            pos=np.zeros((n, 3)),
            quat=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
            rotor=np.zeros((n, 4)),
            force=self.force,
            torque=z3,
            sum_force=z3.copy(),
            sum_torque=z3.copy(),
        )

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
        self.rule: Rule | OwnViewRule = make_rule(
            name, self.n, vehicle=params, barrier=sc.barrier_params, **rule_params
        )
        # under a sensing model each drone decides from its own view: its own copy of the rule (docs/sensing.md)
        self.own_view = self.n > 1 and sensing_stage(sc.sensing, sc.control_period, self.n) is not None
        #: the barrier's measurement-robust margin under a sensing model (None: no barrier, or the oracle)
        self.margin: BarrierMargin | None = None
        if self.own_view:
            filt = self.rule.separation_filter
            if isinstance(filt, BarrierFilter):  # its keep-out widened by the margin (docs/sensing.md)
                self.margin = _barrier_margin(sc, params, filt)
                table = {
                    **(sc.barrier_params or {}),
                    "tracking_margin_m": filt.barrier.tracking_margin_m + 0.5 * self.margin.applied_m,
                }
                if self.margin.applied_m < self.margin.needed_m:  # the views disagree beyond the keep-out's
                    table.setdefault("joint_fallback", False)  # widening: no joint fallback (docs/barrier.md)
                self.rule = make_rule(name, self.n, vehicle=params, barrier=table, **rule_params)
            self.rule = OwnViewRule(self.rule)
        # the attitude and thrust packets the feedforward reads under a sensing model (swarm_mj.sensing.payload)
        self._payload_args = (self.n, channel_config(sc.sensing, sc.control_period).delay_ticks, sc.control_period)
        self._payloads = payload_record(*self._payload_args, float(params.m * params.g))
        self._viewed_ff = Bound(viewed_feedforward, records=2)  # the chunk driver's stage, bound to the records
        # rotor commands desaturated with attitude priority (ours, docs/interpretations.md §1), yaw first given
        # up with the "yaw_last" mixer (docs/vehicles.md, "Mixer")
        self.mixer = sc.mixer_flown
        self.attitude_priority = self.mixer != "clip"
        # the attitude fed back predicted over the rotors' lag (ours, docs/interpretations.md §2)
        lag = sc.lag_horizons
        self.predictor = None if lag is None else AttitudePredictor(self.n, lag[0], lag[1], sc.control_period)
        # the rule may ask the controller to compensate the downwash, when the physics has one
        self.downwash_ff = (
            DownwashFeedforward(self.n, params)
            if self.n > 1 and self.rule.downwash_feedforward and sc.aero.downwash and sc.wind_feedforward
            else None
        )
        self._started = False  # the rule has seen the first observation
        self.U_last = np.zeros((self.n, 4))  # (n, 4) the last command, as the command stage reads it
        self._no_ff, self._no_pred = Feedforward.off(self.n), Predictor.off(self.n)  # stand-ins
        # the Obs fields the command does not read (the neighbours, distances, setpoints)
        n, z3 = self.n, np.zeros((self.n, 3))
        self._unread = (np.zeros((n, n, 3)), np.zeros((n, n)), np.zeros((n, n)), z3, z3, z3)
        self._records: tuple[Control, Feedforward, Predictor] | None = None
        # the command stage the chunk driver compiles, its Python body here with its kernels compiled and
        # bound to this policy's records (_jit.python_body; docs/design.md, "The control period, written once");
        # made at the first command (a policy not used yet pickles)
        self._command: Callable[..., np.ndarray] | None = None

    def _stage_records(self) -> tuple[Control, Feedforward, Predictor]:
        """The records of :func:`swarm_mj.pipeline.period.command` over this policy's own arrays (made again
        after a reset of the controller)."""
        ctl = self.controller
        if self._records is None or self._records[0].att_d is not ctl.att_d:
            # the command stage's buffers (Control.zeros1, scratch, U_out) made here: no allocation per period
            rec = ctl.control_record(self.U_last, priority=self.attitude_priority, yaw_last=self.mixer == "yaw_last")
            ff = self.downwash_ff.record() if self.downwash_ff is not None else self._no_ff
            pred = self.predictor.record() if self.predictor is not None else self._no_pred
            self._records = (rec, ff, pred)
        return self._records

    def control_record(self) -> Control:
        """The controller for :func:`swarm_mj.pipeline.period.command` (its own arrays; ``U_last`` the buffer
        of the last command)."""
        return self._stage_records()[0]

    def payload_record(self) -> PayloadRecord:
        """The packets' payloads each drone holds under a sensing model (swarm_mj.sensing.payload)."""
        return self._payloads

    def feedforward_record(self) -> Feedforward:
        """The downwash feedforward's record (a stand-in with ``on`` False where there is none)."""
        return self._stage_records()[1]

    def predictor_record(self) -> Predictor:
        """The lag prediction's record (a stand-in with ``on`` False where there is none)."""
        return self._stage_records()[2]

    def started(self) -> bool:
        """Past the first command: every memory of the controller (the attitude history, the lag
        prediction's last rates, the feedforward's last thrust) holds a value."""
        return self._started and self.controller.started

    def reset(self) -> None:
        self.controller.reset()
        self._payloads = payload_record(*self._payload_args, float(self.controller.params.m * self.controller.params.g))
        if self.predictor is not None:
            self.predictor.reset()
        self._started = False
        self._records = None

    def _obs_record(self, obs: dict) -> Obs:
        """The observation as the record the command reads: SwarmEnv's own (``Observation.record``) where the
        dict's arrays the command reads are still its arrays, else one of the dict's arrays made C-ordered
        float64 of the observation's shapes (:func:`_f8`; the fields the command does not read: zeros)."""
        rec, n = getattr(obs, "record", None), self.n
        if (
            type(rec) is Obs
            and rec.pos.shape == (n, 3)
            and obs["pos"] is rec.pos
            and obs["vel"] is rec.vel
            and obs["quat"] is rec.quat
            and obs["body_rates"] is rec.omega
            and obs["rpy"] is rec.rpy
            and obs["rpy_rate"] is rec.rpy_rate
            and obs["setpoint_yaw"] is rec.yaw
            and obs["wind_force"] is rec.wf
        ):
            return rec
        n3 = (n, 3)
        rel, mask, dist, sp, spv, spa = self._unread
        return Obs(
            pos=_f8(obs["pos"], n3),
            vel=_f8(obs["vel"], n3),
            quat=_f8(obs["quat"], (n, 4)),
            omega=_f8(obs["body_rates"], n3),
            rpy=_f8(obs["rpy"], n3),
            rpy_rate=_f8(obs["rpy_rate"], n3),
            rel=rel,
            mask=mask,
            dist=dist,
            sp=sp,
            spv=spv,
            spa=spa,
            yaw=_f8(obs["setpoint_yaw"], (n,)),
            wf=_f8(obs["wind_force"], n3),
        )

    @property
    def events(self) -> list[dict]:
        return self.rule.events

    def command(self, obs: dict) -> Command:
        """U1..U4 (n, 4) for the observation, with the references (n, 3) and attitude (n, 3) behind them:
        the control period's first three stages (swarm_mj.pipeline.period.fly_chunk): :meth:`references`,
        :meth:`inputs`, then :meth:`finish`."""
        pos_d, vel_d, acc_d = self.references(obs)
        o, ff = self.inputs(obs)
        return self.finish(o, pos_d, vel_d, acc_d, ff)

    def references(self, obs: dict) -> tuple[Any, Any, Any]:
        """The references (n, 3) of the period (the rule's stage): the formation setpoints adjusted by the
        anti-collision rule (docs/interpretations.md §4; for the drones it steers also the velocity and
        acceleration references, zero = hold x, y), or under a sensing model each drone's copy of the rule
        on its own view (the observation's ``view_*`` keys, swarm_mj.sensing.stage)."""
        if not self._started:
            self.rule.reset(obs["pos"])  # (the flight plan's pads, known to all)
            self._started = True
        if self.own_view:
            rule = self.rule
            assert isinstance(rule, OwnViewRule)
            vp = obs["view_pos"]
            return rule.references_from_view(
                float(obs["time"]), vp, obs["view_setpoint"], obs["view_setpoint_vel"], obs["setpoint_acc"],
                vp[:, 0, 2], obs["view_vel"],
            )  # fmt: skip
        pos_d, vel_d, acc_d = obs["setpoint"], obs["setpoint_vel"], obs["setpoint_acc"]
        if self.n > 1:
            assert isinstance(self.rule, Rule)
            pos_d, vel_d, acc_d = self.rule.references(
                float(obs["time"]), obs["pos"], pos_d, vel_d, acc_d, float(obs["leader_pos"][2])
            )
        return pos_d, vel_d, acc_d

    def inputs(self, obs: dict) -> tuple[Obs, Feedforward | None]:
        """What the controller is given (the inputs' stage): the observation's record and this policy's
        feedforward (None), or under a sensing model each drone's own estimated position and velocity and
        its downwash feedforward from where it believes the others are
        (:func:`~swarm_mj.pipeline.period.viewed_feedforward`, the chunk driver's), added to the known force
        (the feedforward's record then a stand-in that is off)."""
        o = self._obs_record(obs)
        if not self.own_view:
            return o, None
        o = o._replace(pos=_f8(obs["own_pos"], (self.n, 3)), vel=_f8(obs["own_vel"], (self.n, 3)))
        if self.downwash_ff is None:
            return o, None
        gains = self._stage_records()[0].gains
        thrust = self.U_last[:, 0].copy() if self.controller.started else np.full(self.n, gains.m * gains.g)
        k = int(round(float(obs["time"]) / self.controller.T))
        force, f8 = np.empty((self.n, 3)), np.ascontiguousarray
        # what each drone's next packet carries besides its state, and its feedforward from its view
        mask, age = f8(obs["view_mask"] > 0.5), f8(obs["view_age"], dtype=np.float64)
        ff, held = self.downwash_ff.record(), self._payloads
        self._viewed_ff(ff, held, k, f8(obs["view_pos"], dtype=np.float64), mask, age, o.quat, thrust, force)
        return o._replace(wf=o.wf + force), self._no_ff

    def finish(self, o: Obs, pos_d: Any, vel_d: Any, acc_d: Any, ff: Feedforward | None = None) -> Command:
        """The command stage (:func:`swarm_mj.pipeline.period.command`) on the observation record ``o`` and
        the references (n, 3); ``ff``: the feedforward's record (default: this policy's)."""
        ctl, n3 = self.controller, (self.n, 3)
        pos_d, vel_d, acc_d = _f8(pos_d, n3), _f8(vel_d, n3), _f8(acc_d, n3)
        rec, own_ff, pred = self._stage_records()
        if self._command is None:
            self._command = python_body(command)
        U = self._command(rec, own_ff if ff is None else ff, pred, o, pos_d, vel_d, acc_d, not ctl.started)
        ctl.started = True
        if U is rec.U_out:  # the mixer's buffer, rewritten by the next command
            U = U.copy()
        ctl.U = U
        return Command(U=U, pos_d=pos_d, vel_d=vel_d, acc_d=acc_d, att_d=ctl.att_d.copy())

    def __call__(self, obs: dict) -> np.ndarray:
        return self.command(obs).U


def _barrier_margin(sc: Scenario, params: QuadParams, filt: BarrierFilter) -> BarrierMargin:
    """The barrier's margin for the scenario's sensing (:func:`swarm_mj.sensing.margin.barrier_margin`): the
    formation's closest positions at its smallest D, the filter's keep-out width, the vehicle's thrust."""
    spacing = min_slot_spacing(sc.n_followers, float(np.min(sc.diameter_schedule().values)))
    return barrier_margin(
        sc.sensing, sc.control_period, 4.0 * float(params.f_max) / float(params.m), float(params.g), spacing,
        float(filt.radii[0]), filt.barrier.robust_confidence,
    )  # fmt: skip
