"""The sensing stage of the control period: each drone's own view of the swarm (docs/sensing.md,
"The sensing stage").

Every control period, after the physics and before the rules, :meth:`SensingStage.observe` takes the
true states (n, 3) and returns an :class:`OwnView`: the channel's tick (:class:`~.channel.Channel`:
broadcast rate, latency, loss, range, noise) and each receiver's tracks (:mod:`.tracker`). Row i of
every (n, n, ...) field is what drone i believes; its diagonal is the drone's own state as its
estimator gives it. The followers' knowledge of the leader comes through the same channel: each
drone's formation setpoints are built from where *it* believes the leader is (paper §4's slots,
leader + D·offset, moving with the leader's velocity estimated from that belief's differences, as
:func:`~swarm_mj.formation.slots.setpoints_into` estimates it from the true position).

The ``perfect`` preset has no stage (the rules read the true state, as before); every other setting,
zero noise included, flies through it. With no noise, no latency, no loss and the control rate, the
view is the truth bit for bit (:mod:`.tracker`), so such a run flies as ``perfect`` does.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ..formation.slots import setpoints_into
from .channel import Channel
from .margin import age_bound
from .params import SensingParams
from .tracker import TrackState, start_tracks, track_gain, track_step

#: Where a rule is told a drone is that its observer has no entry of (out of range): this far beyond
#: the observer, in x (m), beyond any sensing range a scenario may set.
UNSEEN_M = 1.0e6


class OwnView(NamedTuple):
    """Each drone's own view at one control tick (row i: drone i's)."""

    pos: np.ndarray  # (n, n, 3) where drone i believes drone j is now (m); the diagonal: its own estimate
    vel: np.ndarray  # (n, n, 3) the velocity it believes j flies (m/s); the diagonal: its own
    mask: np.ndarray  # (n, n) bool: i holds a message from j, sent within range (the diagonal False)
    age: np.ndarray  # (n, n) s since j sent what i holds (inf: nothing)
    setpoint: np.ndarray  # (n, n, 3) the formation setpoints drone i flies by (row 0 of each: the leader's plan)
    setpoint_vel: np.ndarray  # (n, n, 3) their velocity references
    setpoint_acc: np.ndarray  # (n, 3) their acceleration references (the true plan's: the leader's row only)
    own_vel: np.ndarray  # (n, 3) each drone's own velocity for its controller (the true one, with its noise)


class SensingStage:
    """One run's sensing: the channel, the tracks and the leader estimates of every drone.
    ``reset(starts, seed, copy)`` at the start of an episode, then :meth:`observe` once per period."""

    def __init__(self, params: SensingParams, period_s: float, n: int) -> None:
        self.params = params
        self.n = n
        self.T = float(period_s)
        self.channel = Channel(params, period_s)
        cfg = self.channel.config
        interval = max(1, int(np.ceil(cfg.interval_ticks - 1e-9))) if cfg.interval_ticks > 0 else 1
        self.spread_ticks = interval  # a message's correction spread over the sender's broadcast interval
        self.alpha = track_gain(
            params.position_noise_m, params.velocity_noise_mps, interval * self.T, cfg.delay_ticks * self.T
        )
        self.tracks: TrackState | None = None
        #: periods after which a sender never heard from is unknown, not on its pad: the age bound of a held
        #: entry at 0.999 (docs/sensing.md, the margin's A_c), in periods
        self.grace_ticks = int(round(age_bound(params, period_s, 0.999)[0] / self.T)) + 1
        self.prev_leader = np.zeros((n, 3))  # (n, 3) each drone's last belief of the leader's position
        self.leader_vel = np.zeros((n, 3))  # (n, 3) its estimate of the leader's velocity
        self.last: OwnView | None = None

    def reset(self, starts: np.ndarray, seed: int, copy: int = 0) -> None:
        """A new episode from the starts (n, 3), the sensing stream seeded by (seed, copy)."""
        self.channel.reset(self.n, seed, copy)
        self.tracks = start_tracks(np.asarray(starts, dtype=np.float64))
        self.prev_leader[:] = np.asarray(starts, dtype=np.float64)[0]
        self.leader_vel[:] = 0.0
        self.ever = np.zeros((self.n, self.n), dtype=bool)  # (n, n) i has held a message from j
        self.prev_pos = np.asarray(starts, dtype=np.float64).copy()  # (n, 3) the last period's positions
        self.prev_t = float("nan")  # s, the last period's time (NaN: none yet)
        self.est_vel = np.zeros((self.n, 3))  # (n, 3) each drone's velocity estimate
        self.last = None

    def observe(
        self,
        k: int,
        pos: np.ndarray,
        vel: np.ndarray,
        leader_plan: tuple[np.ndarray, ...],
        D: float,
        unit_offsets: np.ndarray,
    ) -> OwnView:
        """The view of period k (≥ 0, increasing) from the true pos, vel (n, 3); ``leader_plan``: the
        leader's reference (pos, vel, acc) (3,) of period k (its row of every drone's setpoints), D and the
        unit offsets (n − 1, 3) of the slots."""
        if self.tracks is None:
            raise RuntimeError("SensingStage.observe before reset")
        n, T = self.n, self.T
        t = k * T
        est = self._velocity_estimate(t, pos)
        v = self.channel.observe(t, pos, est)  # (the channel's own tick count starts at its first call)
        s = self.tracks
        held = self.channel.state
        assert held is not None
        track_step(s, v.pos, v.vel, held.held_tick, v.age, T, self.alpha, self.spread_ticks)
        diag = np.arange(n)
        s.x[diag, diag] = v.own_pos
        s.v[diag, diag] = v.own_vel
        # the controller's own velocity: the true one with the own-velocity noise the channel drew
        own_vel = vel.copy() if self.channel.config.sigma_own_vel == 0.0 else vel + (v.own_vel - est)
        gone = ~v.mask & (s.seen_tick >= 0)  # held, dropped since: left the observer's range
        gone[diag, diag] = False
        s.seen_tick[gone] = -1  # its next message starts the track afresh
        self.ever |= v.mask
        believed = s.x.copy()
        # unknown: dropped since held, or never heard from once a message should have come (the pad is
        # believed only until then: a drone that took off out of range is not where it stood)
        unseen = ~v.mask & (self.ever | (k >= self.grace_ticks))
        unseen[diag, diag] = False
        if unseen.any():
            believed[unseen] = v.own_pos[np.nonzero(unseen)[0]] + np.array([UNSEEN_M, 0.0, 0.0])
        # each drone's setpoints: the observation's own function (paper §4) on where it believes the leader is
        sp, spv, spa, yaw = np.empty((n, n, 3)), np.empty((n, n, 3)), np.empty((n, 3)), np.empty(n)
        ref_pos, ref_vel, ref_acc = leader_plan
        for i in range(n):
            setpoints_into(
                k, T, believed[i, 0], self.prev_leader[i], self.leader_vel[i], ref_pos, ref_vel, ref_acc, 0.0, D,
                unit_offsets, sp[i], spv[i], spa, yaw,
            )  # fmt: skip
        self.last = OwnView(
            pos=believed, vel=s.v.copy(), mask=v.mask, age=v.age, setpoint=sp, setpoint_vel=spv, setpoint_acc=spa,
            own_vel=own_vel,
        )  # fmt: skip
        return self.last

    def _velocity_estimate(self, t: float, pos: np.ndarray) -> np.ndarray:
        """Each drone's velocity estimate (n, 3) at time t, what it broadcasts: its position's difference
        over the last period, (p − p_prev)/(t − t_prev) (paper §4's estimate, as the rules make it under
        the oracle; zeros at the first period), updated in place."""
        dt = 0.0 if np.isnan(self.prev_t) else t - self.prev_t
        if dt > 0.0:
            np.subtract(pos, self.prev_pos, out=self.est_vel)
            self.est_vel /= dt
        self.prev_t = t
        self.prev_pos[:] = pos
        return self.est_vel.copy()


def is_oracle(params: SensingParams) -> bool:
    """The ``perfect`` preset, whatever its range: no sensing stage, the rules read the true state and
    apply their own ``sensing_range`` (which a range on the ``perfect`` channel would only repeat: the
    same mask, docs/sensing.md). Any other record (another preset, or ``perfect`` with a noise, rate,
    latency or loss set) flies through :class:`SensingStage`."""
    return params.preset == "perfect" and replace(params, range_m=SensingParams().range_m) == SensingParams()


def sensing_stage(params: SensingParams | None, period_s: float, n: int) -> SensingStage | None:
    """The run's sensing stage, or None for the oracle (:func:`is_oracle`) and for one drone (no others to see)."""
    if params is None or is_oracle(params) or n < 2:
        return None
    return SensingStage(params, period_s, n)


def view_keys(view: OwnView, sensing_range: float) -> dict[str, np.ndarray]:
    """The observation's keys of each drone's own view (SwarmEnv's docstring): ``view_*`` as they are,
    ``own_pos`` (its diagonal), ``own_vel`` (the controller's), and ``neighbours``/``neighbour_mask`` made from the view
    (the relative positions drone i believes, where it holds a message from within ``sensing_range``)."""
    n = view.pos.shape[0]
    diag = np.arange(n)
    own = view.pos[diag, diag]
    rel = view.pos - own[:, None, :]
    near = view.mask & (np.einsum("ijk,ijk->ij", rel, rel) < sensing_range**2)
    near[:, 0] |= view.mask[:, 0]  # the leader: always, when held (the rules' convention)
    near[diag, diag] = False
    return {
        "view_pos": view.pos,
        "view_vel": view.vel,
        "view_mask": view.mask.astype(np.float64),
        "view_age": view.age,
        "view_setpoint": view.setpoint,
        "view_setpoint_vel": view.setpoint_vel,
        "own_pos": own,
        "own_vel": view.own_vel,
        "neighbours": np.where(near[:, :, None], rel, 0.0),
        "neighbour_mask": near.astype(np.float64),
    }
