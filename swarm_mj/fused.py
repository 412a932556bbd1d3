"""The fused built-in path: many control periods of the built-in policy in one compiled call.

``swarm-mj run`` flies the built-in policy (:class:`~swarm_mj.policy.BacksteppingPolicy`) through
:class:`~swarm_mj.env.SwarmEnv`: per control period, Python calls a dozen small kernels and
``mujoco.mj_step`` twice. Once the swarm is formed, :func:`fused_steps` runs the same stages for a
whole chunk of periods in one call, in the same order and with the same kernels, so the results
are the same bit for bit (``tests/integration/test_fused.py`` compares whole runs):

1. anti-collision, the layered rule's *formed* step (its velocity estimates, Fig. 5's check,
   :func:`~swarm_mj.formation.layered.formed_step_kernel`, the merged references; for
   ``jet-aware`` also its slot and overlap checks);
2. where the physics has them, the downwash feedforward (:func:`~swarm_mj.aero.downwash.downwash_kernel`
   on the last thrust commands) and the attitude predicted over the rotors' lag
   (:func:`~swarm_mj.control.lag.predict_kernel`);
3. backstepping, eqs. (17)–(24) (:func:`~swarm_mj.control.backstepping.backstepping_kernel`), then
   the attitude-priority mixer where it is on (:func:`~swarm_mj.mixing.attitude_priority_kernel`);
4. the log row of the period;
5. saturation (:func:`~swarm_mj.mixing.saturate_kernel`) and the wind force held over the period;
6. per physics step: drag + wind into ``xfrc_applied`` (:func:`~swarm_mj.sim.drag_kernel`), the
   produced rotor thrusts of the lagged rotors, the downwash and ground-effect stages (their
   kernels and :func:`~swarm_mj.sim.flush_stage_forces`), then MuJoCo's own ``mj_step`` (called
   from the kernel, :mod:`swarm_mj._mjstep`), then the ground monitor's bookkeeping;
7. the health check (:func:`~swarm_mj.sim.first_unhealthy`, MuJoCo's divergence warnings);
8. the next observation (:func:`~swarm_mj.observation.observe_kernel`, the formation setpoints of
   :func:`~swarm_mj.formation.slots.setpoints_kernel`, the known wind force).

It hands control back to Python (which then flies that period the ordinary way) whenever
something happens that the ordinary path handles with Python code: Fig. 5 has work to do (two
drones within D̄ horizontally, or an offset held; for ``jet-aware`` also slots within D̄ or
outlines overlapping), a contact with another drone or the ground (MuJoCo's ``ncon`` > 0: Python
counts it with :meth:`~swarm_mj.sim.Sim.after_physics_step`, then the kernel resumes at the next
physics step), an unhealthy state (Python raises the usual error), a non-finite command. The chunk
size bounds how long Ctrl-C and the progress bar wait.

:meth:`FusedLoop.why_not` says which runs qualify: ``runner.run``'s built-in policy on one swarm,
under the paper's physics or the realistic preset's stages and ground monitor, the wind without
relative airspeed, and the ``layers``, ``compensated``, ``jet-aware`` or no rule. Everything
else, and every period before the swarm is formed, flies the ordinary path.

**Compiling.** The kernel takes Numba 10–20 s to compile, more than a whole run saves, so the
first run never waits for it: ``runner.run(fused=None)`` (what ``swarm-mj run`` does) uses it when
Numba's on-disk cache holds it for the current sources (:func:`compiled`), and otherwise flies the
ordinary path and starts one detached, low-priority process that compiles it into the cache
(:func:`compile_in_background`) for the runs after. ``fused=True`` compiles it first if needed
(:func:`compile_now`); ``swarm-mj warm-up`` does that for every kernel. The cache is checked against
the sources of every module the kernel calls into (Numba itself checks only this file's).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from . import _jit, _mjstep
from ._jit import jit
from .aero.downwash import DownwashStage, downwash_kernel
from .aero.ground import GroundContacts
from .aero.ground_effect import GroundEffectStage, ground_effect_kernel
from .control.backstepping import backstepping_kernel
from .control.lag import predict_kernel
from .env import StepRecord
from .errors import UserError
from .formation.anticollision import (
    OVERLAP_M,
    CompensatedRule,
    G,
    JetAwareRule,
    LayeredRule,
    NoRule,
    any_below,
    horizontal_distances,
    merge_rows,
    react_needed,
)
from .formation.layered import formed_step_kernel
from .formation.slots import setpoints_kernel
from .mixing import MIX_T, UNMIX_T, attitude_priority_kernel, saturate_kernel
from .observation import observe_kernel
from .sim import (
    DIVERGENCE_WARNING_IDS,
    drag_kernel,
    first_unhealthy,
    floor_gate_kernel,
    flush_stage_forces,
    unmix_kernel,
)

#: :func:`fused_steps` status: the chunk is done; Fig. 5 must act (Python flies this period);
#: a contact to count (then resume); unhealthy (Python raises); a non-finite command.
DONE, REACT, CONTACT, UNHEALTHY, BAD_ACTION = 0, 1, 2, 3, 4

#: Control periods per call: Ctrl-C and the progress bar are served between calls.
CHUNK = 100
#: Periods flown the ordinary way after Fig. 5 acted, before a fused chunk is tried again.
COOL_DOWN = 10


def _samples():
    """One call of every argument type :meth:`FusedLoop.run` passes, with no period to fly."""
    n, K = 2, 3
    z = lambda *s: np.zeros(s)  # noqa: E731
    qpos = z(n, 7)
    qpos[:, 3] = 1.0
    xfrc = z(n + 1, 6)  # MjData.xfrc_applied (nbody, 6): the drones' rows are sliced in the kernel
    warn = np.zeros((8, 2), dtype=np.int32)[:, 1]
    tables = (z(K, 3), z(K, 3), z(K, 3), z(K), z(K), z(n - 1, 3), z(3), z(3), 4.0, z(K, 3), False)
    obs = (z(n, 3), z(n, 3), z(n, 4), z(n, 3), z(n, 3), z(n, 3), z(n, n, 3), z(n, n), z(n, n)) + (
        z(n, 3),
        z(n, 3),
        z(n, 3),
        z(n),
        z(n, 3),
    )
    rule = (True, 0.8, z(n), z(n, 3), z(n, 3), z(1), z(n, 2), z(n, 2), z(n, 2), np.zeros(n, dtype=np.bool_))
    rule += (z(n), z(n), z(n), 6.0, 120.0, 15.0, 4.0, 0.5, G, 4.0, 8.0, 1.5, 5.0, z(n, 3), z(n, 3))
    rule += (np.ones(n, dtype=np.bool_),)
    g = np.ones((n, 3))
    ctl = (g, g, g, g, g, g, np.ones(3), 0.5, 9.81, np.ones(3), np.ones(3), np.ones(3), 0.25, z(n, 2), True, True)
    ctl += (z(n, 3), z(n, 4))
    log = (z(K), z(K, n, 3), z(K, n, 3), z(K, n, 4), z(K, n, 3), z(K, n, 3), z(K, n, 3), z(K, n, 3), z(K, n, 4))
    log += (z(K, n, 4), z(K, 3), z(K, 3), z(K, n, 3), z(K))
    addr = np.uint64(0)  # never called: no period to fly
    sim = (addr, addr, addr, np.zeros(1, dtype=np.int32), warn, qpos, z(n, 6), z(n, 4), xfrc, z(n, 4), z(n, 3))
    sim += (np.ones(3), UNMIX_T, MIX_T, 0.0, 4.5, 2, -0.5, 1e3, np.inf, True, 0.4, np.zeros(3, dtype=np.int32), 0, 4)
    aero = (True, z(n, 4), z(n, 4), z(n, 3), z(n, 3), 1, 1)
    aero += (True, 2, 0.25, 1.2, 0.09, 0.01, 0.01, z(n, 3), z(n, 3))
    aero += (True, 0.25, 0.02, 0.09, 0.02, z(n, 3), z(n, 3), True, z(n, 3), z(n, 3), z(K, n, 3), z(K, n, 3))
    extra = (True, z(n, n), OVERLAP_M, z(1), True, 1.2, 0.09, 0.01, 0.01)
    extra += (z(n, 3), z(n, 4), z(n, 4), z(n, 3), z(n, 3), z(n, 3), z(n, 3))
    extra += (True, 0.025, 1.5, z(n, 3), z(n, 3), True)
    return [(1, 0, 1, False, *sim, 0.01, *tables, *obs, *rule, *ctl, *log, *aero, *extra)]


@jit(samples=_samples, deferred=True)
def fused_steps(  # noqa: PLR0913, PLR0915 - one flat signature is what a compiled call takes cheapest
    k, s0, k_end, python_each,
    # the simulator: mj_step, mjModel, mjData addresses; views into MjData; the saturation
    fn, m_addr, d_addr, ncon, warn, qpos, qvel, ctrl, xfrc, rotor_thrust, wind_now,
    neg_drag, unmix_t, mix_t, f_min, f_max, nsub, floor_z, max_distance, max_tilt,
    gate_on, gate_z, geom_contype, gate_id, gate_solid,
    # the references: trajectory, D(t), slots, leader estimate, sensing, wind force table
    T, ref_pos, ref_vel, ref_acc, ref_yaw, D, unit_offsets, prev_leader, leader_vel, sensing_range, wind_force,
    wind_known,
    # the observation of period k (in) and of the period where the call stops (out)
    o_pos, o_vel, o_quat, o_omega, o_rpy, o_rpy_rate, o_rel, o_mask, o_dist, o_sp, o_spv, o_spa, o_yaw, o_wf,
    # the layered rule's formed step
    rule_on, safety, offset, prev_pos, est_vel, prev_t, path_p, path_v, path_a, blocked, zp, zv, za,
    a_max, jerk, k_v, v_max, tan_tilt, g_rule, vu, au, vd, ad, rule_vel_d, rule_acc_d, steer,
    # backstepping
    a_pos, c1_pos, c2_pos, a_att, c1_att, c2_att, drag_over_m, m, g, inertia, torque_scale, cor, L,
    prev_att_d, exact, use_wind, att_d, U_last,
    # the log rows
    log_t, log_pos, log_vel, log_quat, log_rpy, log_pos_d, log_slot, log_att_d, log_U, log_rotor,
    log_wind_speed, wind_speed, log_wind_force, log_D,
    # the realistic physics (docs/aero.md): rotor lag, the downwash and ground-effect stages, the ground
    lag, act, rotor_command, stage_force, stage_torque, body0, body_step,
    dw_on, dw_n, dw_arm, dw_rho, dw_r, dw_half_cda, dw_half_cda_body, dw_force, dw_torque,
    ge_on, ge_arm, ge_rotor_z, ge_r, ge_z_clip, ge_force, ge_torque, gm_on, vel_before, vel_now, log_dw, log_ge,
    # the controller's parts for it: jet-aware rule, downwash feedforward, lag prediction, mixer
    jet_aware, slot_h, overlap, formation_alt,
    ff_on, ff_rho, ff_r, ff_half_cda, ff_half_cda_body, ff_pos, ff_quat, ff_rotor, ff_force, ff_torque,
    ff_sum_force, ff_sum_torque, pred_on, d_att, k_rate, prev_rate, prev_body, prio_on,
):  # fmt: skip
    """Fly control periods k .. k_end − 1 (see the module docstring); returns (status, k, s): the
    period and physics step (0 = its start) where it stopped. ``s0`` > 0 resumes period k after
    physics step s0 − 1 (a contact Python counted); ``python_each``: Python still holds drones in
    contact (with each other or the ground), so every physics step goes back to it."""
    n = qpos.shape[0]
    zeros1 = np.zeros(n)
    zeros3 = np.zeros((n, 3))
    vel = qvel[:, 0:3]
    # the drones' rows of xfrc_applied (nbody, 6), sliced here: the same layout for any n
    xf = xfrc[body0 : body0 + n * body_step : body_step, 0:3]
    xtorque = xfrc[body0 : body0 + n * body_step : body_step, 3:6]
    pos_v = qpos[:, 0:3]
    quat_v = qpos[:, 3:7]
    while k < k_end:
        if s0 == 0:
            t = k * T
            pos_d = o_sp
            vel_d = o_spv
            acc_d = o_spa
            if rule_on:  # LayeredRule.update (JetAwareRule.update) once every follower is formed
                h = horizontal_distances(o_pos)
                if jet_aware:  # slots within D̄ of each other, or outlines overlapping: Python's work
                    sh = horizontal_distances(o_sp)
                    if any_below(sh, safety):
                        return REACT, k, 0
                    for i in range(1, n):
                        for j in range(n):
                            if h[i, j] < overlap:
                                return REACT, k, 0
                if react_needed(offset, h, safety):
                    return REACT, k, 0
                if jet_aware:
                    slot_h[:] = sh
                    formation_alt[0] = o_pos[0, 2]
                dt = t - prev_t[0]
                if dt > 0.0:
                    for i in range(n):
                        for j in range(3):
                            est_vel[i, j] = o_pos[i, j] - prev_pos[i, j]
                    for i in range(n):
                        for j in range(3):
                            est_vel[i, j] /= dt
                prev_t[0] = t
                prev_pos[:] = o_pos
                out = np.empty((n, 3))
                formed_step_kernel(
                    dt, o_sp, o_pos[0, 2], offset, est_vel[0], path_p, path_v, path_a, blocked, zp, zv, za,
                    a_max, jerk, k_v, v_max, tan_tilt, g_rule, vu, au, vd, ad, out, rule_vel_d, rule_acc_d,
                )  # fmt: skip
                vel_d, acc_d = merge_rows(steer, rule_vel_d, rule_acc_d, o_spv, o_spa)
                pos_d = out
            ext = o_wf
            if ff_on:  # DownwashFeedforward: the jets predicted from the last thrust commands
                ff_pos[:] = o_pos
                ff_quat[:] = o_quat
                for i in range(n):
                    for r in range(4):
                        ff_rotor[i, r] = U_last[i, 0] / 4.0
                ff_sum_force[:] = 0.0
                ff_sum_torque[:] = 0.0
                downwash_kernel(
                    ff_pos, ff_quat, ff_rotor, n, L, ff_rho, ff_r, ff_half_cda, ff_half_cda_body, ff_r,
                    ff_force, ff_torque, ff_sum_force, ff_sum_torque,
                )  # fmt: skip
                ext = o_wf + ff_force
            wind = ext if use_wind else zeros3
            rpy_in = o_rpy
            rate_in = o_rpy_rate
            body_in = o_omega
            if pred_on:  # AttitudePredictor
                rpy_in = np.empty((n, 3))
                rate_in = np.empty((n, 3))
                body_in = np.empty((n, 3))
                predict_kernel(
                    o_rpy, o_rpy_rate, o_omega, prev_rate, prev_body, d_att, k_rate, rpy_in, rate_in, body_in
                )
            omega = body_in if exact else zeros3
            U = backstepping_kernel(
                rpy_in, rate_in, omega, o_pos, o_vel, pos_d, vel_d, acc_d, o_yaw, zeros1, zeros1, wind,
                use_wind, a_pos, c1_pos, c2_pos, a_att, c1_att, c2_att, drag_over_m, m, g, inertia,
                torque_scale, cor, L, T, prev_att_d, False, exact, att_d,
            )  # fmt: skip
            if prio_on:
                Up = np.empty_like(U)
                attitude_priority_kernel(U, unmix_t, mix_t, f_min, f_max, Up)
                U = Up
            U_last[:] = U
            for x in U.flat:
                if not np.isfinite(x):
                    return BAD_ACTION, k, 0
            log_t[k] = t
            log_pos[k] = o_pos
            log_vel[k] = o_vel
            log_quat[k] = o_quat
            log_rpy[k] = o_rpy
            log_pos_d[k] = pos_d
            log_slot[k] = o_sp
            log_att_d[k] = att_d
            log_wind_speed[k] = wind_speed[k]
            log_D[k] = D[k]
            for i in range(n):  # the wind force of period k, held over it
                for j in range(3):
                    wind_now[i, j] = wind_force[k, j]
            saturate_kernel(U, unmix_t, mix_t, f_min, f_max, ctrl, rotor_thrust)
            if lag:
                rotor_command[:] = rotor_thrust
            if gate_on:  # Sim.step's floor gate
                floor_gate_kernel(qpos, qvel, gate_z, T, geom_contype, gate_id, gate_solid)
            log_U[k] = ctrl
            log_wind_force[k] = wind_now
        for s in range(s0, nsub):
            drag_kernel(vel, neg_drag, wind_now, xf)
            if lag:
                unmix_kernel(act, unmix_t, rotor_thrust)
            if dw_on or ge_on:
                if dw_on:
                    downwash_kernel(
                        pos_v, quat_v, rotor_thrust, dw_n, dw_arm, dw_rho, dw_r, dw_half_cda, dw_half_cda_body,
                        dw_r, dw_force, dw_torque, stage_force, stage_torque,
                    )  # fmt: skip
                if ge_on:
                    ground_effect_kernel(
                        pos_v, quat_v, rotor_thrust, ge_arm, ge_rotor_z, ge_r, ge_z_clip, ge_force, ge_torque,
                        stage_force, stage_torque,
                    )  # fmt: skip
                flush_stage_forces(xf, xtorque, stage_force, stage_torque)
            _mjstep.step_call(fn, m_addr, d_addr)
            if ncon[0] > 0 or python_each:
                return CONTACT, k, s + 1
            if gm_on:  # GroundContacts.after_step with no contact: the touchdown speed's bookkeeping
                vel_before[:] = vel_now
                vel_now[:] = vel
        s0 = 0
        if lag:
            unmix_kernel(act, unmix_t, rotor_thrust)
        log_rotor[k] = rotor_thrust
        if dw_on:
            log_dw[k] = dw_force
        if ge_on:
            log_ge[k] = ge_force
        k += 1
        for w in DIVERGENCE_WARNING_IDS:
            if warn[w]:
                return UNHEALTHY, k, 0
        if first_unhealthy(qpos, qvel, n, 1, floor_z, max_distance, max_tilt) != 0:
            return UNHEALTHY, k, 0
        pos, vel_o, quat, omega_o, rpy, rpy_rate, rel, mask, dist = observe_kernel(qpos, qvel, sensing_range)
        sp, spv, spa, yaw = setpoints_kernel(
            k, T, pos[0], prev_leader, leader_vel, ref_pos[k], ref_vel[k], ref_acc[k], ref_yaw[k], D[k], unit_offsets
        )
        o_pos[:] = pos
        o_vel[:] = vel_o
        o_quat[:] = quat
        o_omega[:] = omega_o
        o_rpy[:] = rpy
        o_rpy_rate[:] = rpy_rate
        o_rel[:] = rel
        o_mask[:] = mask
        o_dist[:] = dist
        o_sp[:] = sp
        o_spv[:] = spv
        o_spa[:] = spa
        o_yaw[:] = yaw
        for i in range(n):
            for j in range(3):
                o_wf[i, j] = wind_force[k, j] if wind_known else 0.0
    return DONE, k, 0


# --------------------------------------------------------------------------- compiling


def _sources_hash() -> str:
    """A hash of the sources the fused kernel is compiled from: this module and every kernel module."""
    import importlib.util

    h = hashlib.sha1(usedforsecurity=False)
    extra = ("swarm_mj.fused", "swarm_mj._mjstep", "swarm_mj.aero.downwash", "swarm_mj.aero.ground_effect")
    for name in sorted({*_jit.KERNEL_MODULES, *extra}):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            h.update(Path(spec.origin).read_bytes())
    return h.hexdigest()


def _stamp() -> Path | None:
    """Where the hash of the sources the cached kernel came from is kept (beside Numba's index)."""
    try:
        return Path(fused_steps._cache.cache_path) / "fused.fused_steps.sources"
    except AttributeError:  # no numba
        return None


def compiled() -> bool:
    """The fused kernel is in Numba's on-disk cache, compiled from the current sources."""
    stamp = _stamp()
    if stamp is None or not _mjstep.available() or not _jit.is_cached(fused_steps):
        return False
    try:
        return stamp.read_text() == _sources_hash()
    except OSError:
        return False


def compile_now() -> float:
    """Compile the fused kernel into the cache (dropping a stale one first); returns the seconds spent."""
    t0 = time.perf_counter()
    stamp = _stamp()
    if stamp is None or not _mjstep.available():
        return 0.0
    if not compiled():
        fused_steps._cache.flush()  # Numba would load a stale one
    _jit.compile_samples(fused_steps, _samples)
    try:
        tmp = stamp.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(_sources_hash())
        tmp.replace(stamp)
    except OSError:
        pass
    return time.perf_counter() - t0


def _lock_path() -> Path:
    key = hashlib.sha1(str(_stamp()).encode(), usedforsecurity=False).hexdigest()[:12]
    return Path(tempfile.gettempdir()) / f"swarm_mj-fused-{key}.lock"


def compile_in_background() -> bool:
    """Start one detached, low-priority process compiling the fused kernel into the cache (unless one
    is already at it, or started less than 10 minutes ago); True if one was started."""
    if _stamp() is None or not _mjstep.available():
        return False
    lock = _lock_path()
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            break
        except FileExistsError:
            try:
                if time.time() - lock.stat().st_mtime < 600:
                    return False
                lock.unlink()
            except OSError:
                return False
        except OSError:
            return False
    else:
        return False
    os.close(fd)
    try:
        subprocess.Popen(
            [sys.executable, "-m", "swarm_mj.fused", str(lock)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            close_fds=True,
        )
    except OSError:
        lock.unlink(missing_ok=True)
        return False
    return True


class FusedLoop:
    """The fused path for one run of the built-in policy: :meth:`build`, then :meth:`run` per chunk.

    It shares every array with the environment, the simulator's stages, the policy and the log
    (nothing is copied per period), and leaves them as the ordinary path would after the same
    periods. Build it after ``env.reset()``, for that episode; the arrays that the rule's, the
    controller's and the stages' ``reset`` replace are read at each call."""

    def __init__(self, env, policy, log) -> None:  # noqa: ANN001 - SwarmEnv, BacksteppingPolicy, RunLog
        self.env, self.policy, self.log = env, policy, log
        sim = env.sim
        n = env.n
        self.status = DONE
        self.periods = 0  # control periods flown fused so far
        self._cool = 0  # periods to fly the ordinary way after Fig. 5 acted
        self._prev_t = np.zeros(1)
        self._formation_alt = np.zeros(1)
        self._U = np.zeros((n, 4))
        self._obs = tuple(
            np.zeros(s) for s in ((n, 3), (n, 3), (n, 4), (n, 3), (n, 3), (n, 3), (n, n, 3), (n, n), (n, n))
        ) + (np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)))
        d = sim.data
        c = np.ascontiguousarray
        ref = env.reference
        self._sim_static = (
            np.uint64(_mjstep.mj_step_address() or 0), np.uint64(sim.model._address), np.uint64(d._address),
            _mjstep.ncon_view(d), sim._warnings, sim.qpos, sim.qvel, sim.ctrl, d.xfrc_applied,
            sim.rotor_thrust,
        )  # fmt: skip
        self._sim_rest = (
            c(sim.drag.neg_drag, dtype=float), sim._unmix_t, sim._mix_t, float(sim._f_min), float(sim._f_max),
            int(sim.n_substeps), float(sim.floor_z), float(sim.max_distance), float(sim.max_tilt),
        )  # fmt: skip
        fid, solid, z_near = sim._gate or (0, 0, 0.0)  # Sim's floor gate (none: never switched on)
        self._gate_args = (float(z_near), sim.model.geom_contype, int(fid), int(solid))
        wind = env.wind
        self._tables = (
            c(ref.pos, dtype=float), c(ref.vel, dtype=float), c(ref.acc, dtype=float), c(ref.yaw, dtype=float),
            c(env.D, dtype=float), env._unit_offsets,
        )  # fmt: skip
        self._wind = (c(wind.force, dtype=float), bool(env._wind_known))
        self._layered = isinstance(policy.rule, LayeredRule) and n > 1  # policy.command applies no rule to one drone
        self._jet_aware = self._layered and isinstance(policy.rule, JetAwareRule)
        z, e = np.zeros((n, 3)), np.zeros((n, 2))
        self._no_rule = (
            False, 0.8, np.zeros(n), z.copy(), z.copy(), self._prev_t, e.copy(), e.copy(), e.copy(),
            np.zeros(n, dtype=bool), np.zeros(n), np.zeros(n), np.zeros(n), 1.0, 1.0, 1.0, 1.0, 1.0, G,
            1.0, 1.0, 1.0, 1.0, z.copy(), z.copy(), np.zeros(n, dtype=bool),
        )  # fmt: skip
        ctl = policy.controller
        p = ctl.params
        self._ctl_static = (
            ctl._a_pos, ctl._c1_pos, ctl._c2_pos, ctl._a_att, ctl._c1_att, ctl._c2_att, ctl._drag_over_m,
            float(p.m), float(p.g), ctl._inertia, ctl._torque_scale, ctl._cor, float(p.L),
        )  # fmt: skip
        self._ctl_flags = (ctl.attitude_map == "exact", bool(ctl.wind_feedforward))
        self._log_args = (
            log.t, log.pos, log.vel, log.quat, log.rpy, log.pos_d, log.slot, log.att_d, log.U, log.rotor,
            log.wind_speed, c(wind.speed, dtype=float), log.wind_force, log.D,
        )  # fmt: skip
        self._stages = {type(st): st for st in sim.force_stages}
        self._ground = next((mon for mon in sim.monitors if isinstance(mon, GroundContacts)), None)
        N1 = np.zeros((n, 3))
        self._empty3 = (N1, N1.copy())  # stand-ins for the arrays of a stage or monitor not there
        self._empty_log = np.zeros((1, n, 3))
        self._no_lag = np.zeros((n, 4))

    def _rule_args(self) -> tuple:
        """The layered rule's state, read at each call: ``reset`` replaces its arrays."""
        if not self._layered:
            return self._no_rule
        rule = self.policy.rule
        (vu, au), (vd, ad) = rule.z_up, rule.z_down_formed
        return (
            True, float(rule.safety), rule.offset, rule._prev_pos, rule.vel, self._prev_t, rule.path_p,
            rule.path_v, rule.path_a, rule.blocked, rule.zp, rule.zv, rule.za, float(rule.a_max),
            float(rule.jerk), float(rule.k_v), float(rule.v_max), float(rule.tan_tilt), G, float(vu),
            float(au), float(vd), float(ad), rule.vel_d, rule.acc_d, rule._followers,
        )  # fmt: skip

    def _aero_args(self) -> tuple:
        """The realistic physics' arrays and constants (stand-ins where a part is off)."""
        sim, log = self.env.sim, self.log
        e3 = self._empty3
        dw = self._stages.get(DownwashStage)
        ge = self._stages.get(GroundEffectStage)
        gm = self._ground
        lag = bool(sim.motor_lag)
        out: tuple = (lag, sim._act if lag else self._no_lag, sim.rotor_command, sim._force, sim._torque)
        ids = np.asarray(sim.world.body_ids)
        out += (int(ids[0]), int(ids[1] - ids[0]) if len(ids) > 1 else 1)
        if dw is not None:
            out += (True, int(dw.n_per_copy), float(dw.arm), float(dw.rho), float(dw.rotor_radius))
            out += (float(dw.half_cda), float(dw.half_cda_body), dw.force, dw.torque)
        else:
            out += (False, 1, 0.0, 0.0, 0.0, 0.0, 0.0, *e3)
        if ge is not None:
            out += (True, float(ge.arm), float(ge.rotor_z), float(ge.rotor_radius), float(ge.z_clip))
            out += (ge.force, ge.torque)
        else:
            out += (False, 0.0, 0.0, 0.0, 0.0, *e3)
        out += (True, gm._vel_before, gm._vel_now) if gm is not None else (False, *e3)
        dw_log = log.downwash if dw is not None and log.downwash is not None else self._empty_log
        ge_log = log.ground_effect if ge is not None and log.ground_effect is not None else self._empty_log
        return (*out, dw_log, ge_log)

    def _policy_args(self) -> tuple:
        """The controller's parts for the realistic physics: jet-aware rule, feedforward, prediction, mixer."""
        policy, n = self.policy, self.env.n
        rule = policy.rule
        slot_h = rule._slot_h if self._jet_aware else np.zeros((n, n))
        out: tuple = (self._jet_aware, slot_h, OVERLAP_M, self._formation_alt)
        ff = policy.downwash_ff
        if ff is not None:
            _, _, rho, r, half_cda, half_cda_body, _ = ff._args
            out += (True, float(rho), float(r), float(half_cda), float(half_cda_body), ff._pos, ff._quat, ff._rotor)
            out += (ff.force, ff._torque, ff._sum_force, ff._sum_torque)
        else:
            z3, z4 = np.zeros((n, 3)), np.zeros((n, 4))
            out += (False, 0.0, 0.0, 0.0, 0.0, z3, np.zeros((n, 4)), z4, z3.copy(), z3.copy(), z3.copy(), z3.copy())
        pred = policy.predictor
        if pred is not None:
            out += (True, float(pred.d_att), float(pred.k_rate), pred._prev_rate, pred._prev_body)
        else:
            out += (False, 0.0, 0.0, np.zeros((n, 3)), np.zeros((n, 3)))
        return (*out, bool(policy.attitude_priority))

    # ------------------------------------------------------------------ eligibility
    @staticmethod
    def why_not(env, policy) -> str | None:  # noqa: ANN001, PLR0911
        """Why this run cannot fly fused (None: it can)."""
        sim, sc = env.sim, env.scenario
        if not _mjstep.available():
            return "no compiled mj_step here"
        if env.action_mode != "thrust" or sim.n_copies != 1:
            return "not the built-in run"
        if not sim._fused:
            return "force stages other than drag and wind first"
        kinds = [type(st) for st in sim._extra]
        if kinds not in ([], [DownwashStage], [GroundEffectStage], [DownwashStage, GroundEffectStage]):
            return "force stages other than the realistic preset's"
        if any(not isinstance(mon, GroundContacts) for mon in sim.monitors) or len(sim.monitors) > 1:
            return "monitors other than the ground's"
        if env.wind.relative_airspeed:
            return "wind on the relative airspeed"
        ids = np.asarray(sim.world.body_ids)
        if len(ids) > 1 and not (np.diff(ids) == ids[1] - ids[0]).all():
            return "drone bodies not evenly spaced in the model"
        rule = policy.rule
        if sc.n_drones > 1 and type(rule) not in (LayeredRule, CompensatedRule, JetAwareRule, NoRule):
            return f"the {rule.name!r} rule"
        return None

    @classmethod
    def build(cls, env, policy, log, *, compile: bool = False, announce=None) -> FusedLoop | None:  # noqa: ANN001, A002
        """The fused path of this run, or None when it does not qualify (:meth:`why_not`) or is not
        compiled yet: then ``compile`` True compiles it now, False starts :func:`compile_in_background`
        (``announce`` gets one line saying so) and the run flies the ordinary path."""
        if cls.why_not(env, policy) is not None:
            return None
        if not compiled():
            if not compile:
                if compile_in_background() and announce is not None:
                    announce("compiling the fused path in the background (later runs use it)")
                return None
            compile_now()
        return cls(env, policy, log)

    def ready(self) -> bool:
        """The run is where a fused chunk can start: past its first period, every follower formed and
        every drone in the air, no contact pending, the controller's memories started, and Fig. 5
        idle for a while."""
        if self._cool > 0:
            self._cool -= 1
            return False
        env, policy = self.env, self.policy
        if env.k < 1 or not policy._started or policy.controller._prev_att_d is None or env.sim._pairs_in_contact:
            return False
        if policy.predictor is not None and policy.predictor._first:
            return False
        if policy.downwash_ff is not None and not policy._ff_started:
            return False
        gm = self._ground
        if gm is not None and (not gm._all_airborne or gm._any_contact):
            return False
        rule = policy.rule
        return not self._layered or (rule._all_formed and rule._prev_t is not None and not self._slot_yield(rule))

    def _slot_yield(self, rule) -> bool:  # noqa: ANN001
        return self._jet_aware and bool(rule._slot_yield)

    # ------------------------------------------------------------------ one chunk
    def run(self, k_end: int) -> int:
        """Fly from the environment's period to ``k_end`` (or to where the kernel hands back); returns the
        period reached, with the environment, policy and log as the ordinary path leaves them (where
        it stopped on an error, the period that failed: then :meth:`raise_if_stopped` raises it)."""
        env, policy, sim = self.env, self.policy, self.env.sim
        obs = env._obs
        bufs = self._obs
        for buf, key in zip(bufs, _OBS_KEYS, strict=True):
            buf[...] = obs[key] if key != "dist" else env._dist
        rule = policy.rule
        if self._layered:
            self._prev_t[0] = rule._prev_t
        ctl = policy.controller
        self._U[:] = ctl.U  # the last command (the downwash feedforward's thrust)
        sim_args = (*self._sim_static, sim.wind.force, *self._sim_rest, bool(sim.floor_gate), *self._gate_args)
        ref_args = (float(env.T), *self._tables, env._prev_leader, env._leader_vel, float(env.scenario.sensing_range))
        rest = (
            *bufs, *self._rule_args(), *self._ctl_static, ctl._prev_att_d, *self._ctl_flags, ctl.att_d, self._U,
            *self._log_args, *self._aero_args(), *self._policy_args(),
        )  # fmt: skip
        k, s = env.k, 0
        with _mjstep.profiler_paused():  # MuJoCo's profiling clock off, as in Sim.step
            while True:
                status, k, s = fused_steps(k, s, k_end, self._python_each(), *sim_args, *ref_args, *self._wind, *rest)
                if status == CONTACT:
                    sim.after_physics_step()  # contacts and monitors, as Sim.step after that physics step
                    continue
                break
        self.status = status
        self.periods += k - env.k
        ctl.U = self._U.copy()
        if self._layered:
            rule._prev_t = float(self._prev_t[0])
            if self._jet_aware and k > env.k:
                rule._formation_alt = float(self._formation_alt[0])
        if status == REACT:
            self._cool = COOL_DOWN
        env.k = k
        env._contacts_seen = sim.contact_events
        if status == UNHEALTHY:
            return k - 1  # the period whose step failed (env.k is past it, as SwarmEnv.step leaves it)
        if status == BAD_ACTION:
            return k
        env._obs = env._observation(*(b.copy() for b in bufs))
        self._record(k)
        if k >= env.n_steps:
            env._done = True
        return k

    def _python_each(self) -> bool:
        """Python must see every physics step: drones in contact with each other or the ground."""
        gm = self._ground
        return bool(self.env.sim._pairs_in_contact) or (gm is not None and gm._any_contact)

    def raise_if_stopped(self) -> None:
        """Raise what the ordinary path raises where the last :meth:`run` stopped: the simulator's
        :class:`~swarm_mj.errors.SimulationDiverged` (naming why), or the environment's error for a
        non-finite command."""
        if self.status == UNHEALTHY:
            self.env.sim.check()  # raises SimulationDiverged, naming why
            raise AssertionError("internal: the fused path found a state the simulator calls healthy")
        if self.status == BAD_ACTION:
            raise UserError("action contains NaN or inf")

    def _record(self, k: int) -> None:
        """The environment's record of the last period flown (as :meth:`SwarmEnv.step` leaves it)."""
        log, j = self.log, k - 1
        if j >= 0:
            aero = self.env.sim.stage_forces()
            self.env.last_applied = StepRecord(
                j * self.env.T,
                log.U[j].copy(),
                log.rotor[j].copy(),
                log.wind_force[j].copy(),
                None,
                None,
                None,
                None,
                aero,
            )


_OBS_KEYS = (
    "pos", "vel", "quat", "body_rates", "rpy", "rpy_rate", "neighbours", "neighbour_mask", "dist",
    "setpoint", "setpoint_vel", "setpoint_acc", "setpoint_yaw", "wind_force",
)  # fmt: skip


def _background_main(argv: list[str]) -> None:
    """The process :func:`compile_in_background` starts: compile, then drop the lock file ``argv[0]``."""
    try:
        if hasattr(os, "nice"):
            os.nice(10)
        compile_now()
    finally:
        if argv:
            Path(argv[0]).unlink(missing_ok=True)


if __name__ == "__main__":  # python -m swarm_mj.fused LOCK: through the imported module, the one runs use
    import importlib

    importlib.import_module("swarm_mj.fused")._background_main(sys.argv[1:])
