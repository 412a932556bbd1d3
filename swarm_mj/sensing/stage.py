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

from .._jit import Bound, jit, warm_module
from ..formation.slots import setpoints_into
from .channel import Channel, ChannelConfig, ChannelState, channel_tick
from .margin import age_bound
from .params import SensingParams, sensing_preset
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


class SenseRecord(NamedTuple):
    """One run's sensing as a record of arrays (built by :meth:`SensingStage.reset`): the channel, the
    tracks, each drone's leader estimate, and the view of the last tick (row i: drone i's)."""

    cfg: ChannelConfig  # the channel's static numbers
    ch: ChannelState  # the channel's state (its held messages: ch.held_*)
    tr: TrackState  # every receiver's track of every sender
    T: float  # the control period (s)
    alpha: float  # the tracks' gain (tracker.track_gain)
    spread: int  # ticks a message's correction is spread over (the sender's broadcast interval)
    grace: int  # periods after which a sender never heard from is unknown, not on its pad
    k0: np.ndarray  # (1,) int64: the period of the channel's first tick (its own count starts there)
    prev_pos: np.ndarray  # (n, 3) the last period's true positions (the broadcast velocity's difference)
    prev_t: np.ndarray  # (1,) s: the last period's time (NaN: none yet)
    est_vel: np.ndarray  # (n, 3) each drone's velocity estimate, what it broadcasts
    prev_leader: np.ndarray  # (n, 3) each drone's last belief of the leader's position
    leader_vel: np.ndarray  # (n, 3) its estimate of the leader's velocity
    ever: np.ndarray  # (n, n) bool: i has held a message from j
    own_pos: np.ndarray  # (n, 3) each drone's own position for its controller (the channel's, with its noise)
    chan_vel: np.ndarray  # (n, 3) its own velocity as the channel gives it (the estimate, with its noise)
    own_vel: np.ndarray  # (n, 3) the controller's own velocity: the true one with the own-velocity noise
    pos: np.ndarray  # (n, n, 3) where drone i believes drone j is (the diagonal: its own estimate)
    vel: np.ndarray  # (n, n, 3) the velocity it believes j flies
    mask: np.ndarray  # (n, n) bool: i holds a message from j, sent within range
    age: np.ndarray  # (n, n) s since j sent what i holds (inf: nothing)
    sp: np.ndarray  # (n, n, 3) the formation setpoints drone i flies by
    spv: np.ndarray  # (n, n, 3) their velocity references
    spa: np.ndarray  # (n, 3) their acceleration references (the true plan's)
    yaw: np.ndarray  # (n,) the yaw references (zero; scratch)


@jit(on_demand=True, samples=lambda: _tick_samples())
def sense_step(rec, rng, k, pos, vel, ref_pos, ref_vel, ref_acc, D, unit_offsets) -> None:
    """The view of period k (≥ 0, increasing) into ``rec`` from the true pos, vel (n, 3), drawing from the
    run's generator ``rng``: each drone's velocity estimate (its position's difference over the last period,
    paper §4's, zeros at the first), the channel's tick, every track's, the diagonal set to each drone's own
    estimate, entries dropped or never heard from moved out of sight (:data:`UNSEEN_M`), and each drone's
    formation setpoints from where it believes the leader is (``ref_*`` (3,): the leader's plan of period k,
    D and the unit offsets (n − 1, 3) of the slots). Both drivers of the control period call it (a call, not
    inlined: compiled once for every driver's signature)."""
    n = pos.shape[0]
    T = rec.T
    t = k * T
    dt = 0.0 if np.isnan(rec.prev_t[0]) else t - rec.prev_t[0]
    for i in range(n):
        for c in range(3):
            if dt > 0.0:
                rec.est_vel[i, c] = (pos[i, c] - rec.prev_pos[i, c]) / dt
            rec.prev_pos[i, c] = pos[i, c]
    rec.prev_t[0] = t
    if rec.ch.tick[0] < 0:
        rec.k0[0] = k
    channel_tick(rec.ch, rec.cfg, k - rec.k0[0], pos, rec.est_vel, rng, rec.own_pos, rec.chan_vel, rec.age)
    ch, tr = rec.ch, rec.tr
    track_step(tr, ch.held_pos, ch.held_vel, ch.held_tick, rec.age, T, rec.alpha, rec.spread)
    for i in range(n):
        for c in range(3):
            tr.x[i, i, c] = rec.own_pos[i, c]
            tr.v[i, i, c] = rec.chan_vel[i, c]
            # the controller's own velocity: the true one with the own-velocity noise the channel drew
            noise = rec.chan_vel[i, c] - rec.est_vel[i, c]
            rec.own_vel[i, c] = vel[i, c] if rec.cfg.sigma_own_vel == 0.0 else vel[i, c] + noise
    for i in range(n):
        for j in range(n):
            held = ch.held_tick[i, j] >= 0  # (the diagonal never holds anything)
            rec.mask[i, j] = held
            if not held and tr.seen_tick[i, j] >= 0 and i != j:  # held, dropped since: left the range
                tr.seen_tick[i, j] = -1  # its next message starts the track afresh
            rec.ever[i, j] = rec.ever[i, j] or held
            for c in range(3):
                rec.pos[i, j, c] = tr.x[i, j, c]
                rec.vel[i, j, c] = tr.v[i, j, c]
            # unknown: dropped since held, or never heard from once a message should have come (the pad is
            # believed only until then: a drone that took off out of range is not where it stood)
            if i != j and not held and (rec.ever[i, j] or k >= rec.grace):
                rec.pos[i, j, 0] = rec.own_pos[i, 0] + UNSEEN_M
                rec.pos[i, j, 1] = rec.own_pos[i, 1] + 0.0
                rec.pos[i, j, 2] = rec.own_pos[i, 2] + 0.0
    for i in range(n):  # each drone's setpoints: the observation's own function (paper §4) on its leader belief
        setpoints_into(k, T, rec.pos[i, 0], rec.prev_leader[i], rec.leader_vel[i], ref_pos, ref_vel, ref_acc, 0.0, D,
                       unit_offsets, rec.sp[i], rec.spv[i], rec.spa, rec.yaw)  # fmt: skip


def _tick_samples():
    stage = SensingStage(sensing_preset("mocap"), 0.01, 3)
    stage.reset(np.zeros((3, 3)), 0)
    z, z1 = np.zeros((3, 3)), np.zeros(3)
    return [(stage.rec, stage.rng, 0, z, z, z1, z1, z1, 0.5, np.zeros((2, 3)))]


class SensingStage:
    """One run's sensing: the channel, the tracks and the leader estimates of every drone, as one record
    (:class:`SenseRecord`, :meth:`record`) that :func:`sense_step` advances. ``reset(starts, seed, copy)`` at
    the start of an episode, then :meth:`observe` once per period (or the chunk driver's ticks)."""

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
        #: periods after which a sender never heard from is unknown, not on its pad: the age bound of a held
        #: entry at 0.999 (docs/sensing.md, the margin's A_c), in periods
        self.grace_ticks = int(round(age_bound(params, period_s, 0.999)[0] / self.T)) + 1
        self.rec: SenseRecord | None = None
        self.last: OwnView | None = None
        self._step = Bound(sense_step, records=2)

    @property
    def rng(self) -> np.random.Generator:
        """The run's sensing generator (the channel's: seeded by (seed, copy) at :meth:`reset`)."""
        if self.channel.rng is None:
            raise RuntimeError("SensingStage used before reset")
        return self.channel.rng

    def record(self) -> SenseRecord:
        """The stage's record (:class:`SenseRecord`), the chunk driver's and :meth:`observe`'s."""
        if self.rec is None:
            raise RuntimeError("SensingStage used before reset")
        return self.rec

    def reset(self, starts: np.ndarray, seed: int, copy: int = 0) -> None:
        """A new episode from the starts (n, 3), the sensing stream seeded by (seed, copy)."""
        n = self.n
        starts = np.asarray(starts, dtype=np.float64)
        self.channel.reset(n, seed, copy)
        state = self.channel.state
        assert state is not None
        self.rec = SenseRecord(
            cfg=self.channel.config, ch=state, tr=start_tracks(starts), T=self.T, alpha=float(self.alpha),
            spread=int(self.spread_ticks), grace=int(self.grace_ticks), k0=np.zeros(1, dtype=np.int64),
            prev_pos=starts.copy(), prev_t=np.full(1, np.nan), est_vel=np.zeros((n, 3)),
            prev_leader=np.broadcast_to(starts[0], (n, 3)).copy(), leader_vel=np.zeros((n, 3)),
            ever=np.zeros((n, n), dtype=bool), own_pos=np.zeros((n, 3)), chan_vel=np.zeros((n, 3)),
            own_vel=np.zeros((n, 3)), pos=np.zeros((n, n, 3)), vel=np.zeros((n, n, 3)),
            mask=np.zeros((n, n), dtype=bool), age=np.full((n, n), np.inf), sp=np.zeros((n, n, 3)),
            spv=np.zeros((n, n, 3)), spa=np.zeros((n, 3)), yaw=np.zeros(n),
        )  # fmt: skip
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
        unit offsets (n − 1, 3) of the slots: :func:`sense_step`, then :meth:`view`."""
        rec = self.record()
        p, v, o, (rp, rv, ra) = (_f8(x) for x in (pos, vel, unit_offsets, leader_plan))
        self._step(rec, self.rng, int(k), p, v, rp, rv, ra, float(D), o)
        return self.view()

    def view(self) -> OwnView:
        """The view of the last tick (copies of the record's arrays), kept as :attr:`last`."""
        r = self.record()
        self.last = OwnView(
            pos=r.pos.copy(), vel=r.vel.copy(), mask=r.mask.copy(), age=r.age.copy(), setpoint=r.sp.copy(),
            setpoint_vel=r.spv.copy(), setpoint_acc=r.spa.copy(), own_vel=r.own_vel.copy(),
        )  # fmt: skip
        return self.last


def _f8(x) -> np.ndarray:  # noqa: ANN001 - an array or a tuple of arrays
    """``x`` as C-ordered float64 (the types the stage's compiled tick is bound to)."""
    return np.ascontiguousarray(x, dtype=np.float64)


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
    warm_module(__name__)  # its tick compiled (or loaded from the cache) before a run's clock starts
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
