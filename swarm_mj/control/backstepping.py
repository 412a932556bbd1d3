"""Backstepping controller of paper §3.1, eqs. (4)–(24), vectorised over drones.

Every degree of freedom i ∈ {φ, θ, ψ, x, y, z} with gains (a, b) = (α_{2i−1}, α_{2i}) uses

    e1 = x_d − x                                  (eq. 4)
    e2 = ẋ_d + a·e1 − ẋ                            (eqs. 8–9, 12)
    v  = ẍ_d + e1 + a·e2 − a²·e1 + b·e2            (common part of eqs. 17–20, 23–24)

so that the error system is ė1 = e2 − a·e1, ė2 = −e1 − b·e2, with characteristic
polynomial s² + (a + b)s + (1 + a·b). The axis-specific terms are added on top:

    U2 = Ix/L (v_φ − (Iy − Iz)/Ix θ̇ψ̇)                    (17)
    U3 = Iy/L (v_θ − (Iz − Ix)/Iy φ̇ψ̇)                    (19)
    U4 = Iz/L (v_ψ − (Ix − Iy)/Iz φ̇θ̇)                    (20)
    U1 = m/(cos φ cos θ) (v_z + g + Kz ż/m)                (18)
    Ux = m/U1 (v_x + Kx ẋ/m − F^w_x/m)                    (23, docs/interpretations.md §2: F^w/m, not F^w/Ix)
    Uy = m/U1 (v_y + Ky ẏ/m − F^w_y/m)                    (24)
    φ_d = asin(Ux sin ψ_d − Uy cos ψ_d)                   (21)
    θ_d = asin((Ux cos ψ_d + Uy sin ψ_d)/cos φ_d)         (22)

φ_d and θ_d are clipped to ±45°, the asin arguments to [−1, 1], U1 has a small
positive floor (docs/interpretations.md §2). The desired-attitude derivatives that the paper leaves
out are finite differences of the commanded φ_d, θ_d over the control period T
(docs/interpretations.md §2); ψ_d and its derivatives come from the reference.

The state is read from MuJoCo: φ, θ, ψ from the quaternion and φ̇, θ̇, ψ̇ from the
body angular velocity, see :mod:`swarm_mj.physics.state`.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .._jit import bind, jit
from ..errors import UserError
from ..paper import TABLE4_GAINS
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.records import Control, Gains

__all__ = ["TABLE4_GAINS", "Backstepping", "backstepping_kernel", "check_gains", "load_gains"]
MAX_TILT = np.deg2rad(45.0)
U1_FLOOR = 0.05  # N


def load_gains(path: str | Path) -> np.ndarray:
    """Read a gains TOML file (``gains = [12 floats]``, as written by ``swarm-mj tune``)."""
    path = Path(path)
    if not path.exists():
        raise UserError("gains file not found", where=str(path))
    if path.is_dir():
        raise UserError("is a folder, not a gains file", where=str(path))
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"not valid TOML: {exc}", where=str(path)) from None
    except OSError as exc:
        raise UserError(f"cannot read the gains file: {exc.strerror or exc}", where=str(path)) from None
    if "gains" not in data:
        raise UserError("missing field 'gains' (12 numbers)", where=f"{path}: gains")
    return check_gains(data["gains"], where=f"{path}: gains")


def check_gains(gains, n: int | None = None, where: str = "gains") -> np.ndarray:
    """Validate gains as (12,) or (n, 12) positive finite numbers."""
    try:
        g = np.asarray(gains, dtype=float)
    except (TypeError, ValueError):
        raise UserError("gains must be 12 numbers", where=where) from None
    if g.shape[-1:] != (12,) or g.ndim > 2 or (g.ndim == 2 and n is not None and g.shape[0] != n):
        raise UserError(f"gains must have shape (12,) or (n_drones, 12), got {g.shape}", where=where)
    if not np.isfinite(g).all() or (g <= 0).any():
        raise UserError("every gain must be a positive finite number (paper: α_s > 0)", where=where)
    return g


class Backstepping:
    """Backstepping controller for n drones (one call computes U1..U4 for all).

    gains: (12,) shared or (n, 12) per drone (α1..α12 of Table 4).
    wind_feedforward: use the wind force F^w in eqs. (23)–(24) (paper default: on).
    """

    def __init__(
        self,
        n: int,
        gains: np.ndarray | None = None,
        *,
        params: QuadParams = DEFAULT_PARAMS,
        control_period: float = 0.01,
        wind_feedforward: bool = True,
        attitude_map: str = "exact",
    ) -> None:
        self.n = n
        self.params = params
        self.T = float(control_period)
        self.wind_feedforward = bool(wind_feedforward)
        if attitude_map not in ("exact", "paper"):
            raise UserError(f"attitude_map must be 'exact' or 'paper', got {attitude_map!r}")
        self.attitude_map = attitude_map
        g = check_gains(TABLE4_GAINS if gains is None else gains, n)
        g = np.broadcast_to(g, (n, 12)).astype(float)
        self.gains = g
        # Column layout (n, 3): attitude (φ, θ, ψ) and position (x, y, z).
        self._a_att, self._b_att = g[:, [0, 2, 4]].copy(), g[:, [1, 3, 5]].copy()
        self._a_pos, self._b_pos = g[:, [6, 8, 10]].copy(), g[:, [7, 9, 11]].copy()
        # v = ẍ_d + (1 − a²)·e1 + (a + b)·e2 is the common part written with fewer operations
        self._c1_att, self._c2_att = 1.0 - self._a_att**2, self._a_att + self._b_att
        self._c1_pos, self._c2_pos = 1.0 - self._a_pos**2, self._a_pos + self._b_pos
        self._zeros3 = np.zeros((n, 3))
        self._zeros1 = np.zeros(n)
        p = params
        self._inertia = np.array([p.Ix, p.Iy, p.Iz])
        # Coriolis coefficients of eqs. (17), (19), (20).
        self._cor = np.array([(p.Iy - p.Iz) / p.Ix, (p.Iz - p.Ix) / p.Iy, (p.Ix - p.Iy) / p.Iz])
        self._torque_scale = self._inertia / p.L
        self._drag_over_m = p.drag / p.m
        #: the constants of eqs. (17)–(24) as one record (what the kernel takes)
        #: backstepping_kernel bound to the record and C-ordered float64 inputs (:func:`swarm_mj._jit.bind`)
        self._kernel: Callable[..., np.ndarray] | None = None
        self.record = Gains(
            a_pos=self._a_pos,
            c1_pos=self._c1_pos,
            c2_pos=self._c2_pos,
            a_att=self._a_att,
            c1_att=self._c1_att,
            c2_att=self._c2_att,
            drag_over_m=self._drag_over_m,
            m=float(p.m),
            g=float(p.g),
            inertia=self._inertia,
            torque_scale=self._torque_scale,
            cor=self._cor,
            L=float(p.L),
            T=self.T,
        )
        self.reset()

    def reset(self) -> None:
        """Forget the finite-difference history of the commanded attitude."""
        #: a command since the reset (the first one has zero desired-attitude rates; ``prev_att_d`` is its memory)
        self.started = False
        self.prev_att_d = np.zeros((self.n, 2))  # (n, 2) previous (φ_d, θ_d)
        self.att_d = np.zeros((self.n, 3))  # (n, 3) last commanded (φ_d, θ_d, ψ_d)
        self.U = np.zeros((self.n, 4))  # (n, 4) last output

    def control_record(self, U_last: np.ndarray, *, priority: bool, yaw_last: bool = False) -> Control:
        """This controller as :func:`swarm_mj.pipeline.period.command` takes it: its gains record and attitude
        memories (valid until :meth:`reset`), ``U_last`` (n, 4) the caller's buffer of the last command, the
        attitude-priority mixer on when ``priority`` (the vehicle's rotor limits; with ``yaw_last`` the mixer
        that gives up yaw first, :func:`~swarm_mj.physics.mixing.yaw_last`), new stage buffers."""
        p, n = self.params, self.n
        return Control(
            gains=self.record,
            prev_att_d=self.prev_att_d,
            att_d=self.att_d,
            U_last=U_last,
            exact=self.attitude_map == "exact",
            use_wind=self.wind_feedforward,
            priority=bool(priority or yaw_last),
            yaw_last=bool(yaw_last),
            unmix_t=p.unmix_t,
            mix_t=p.mix_t,
            f_min=float(p.f_min),
            f_max=float(p.f_max),
            zeros1=np.zeros(n),
            scratch=np.zeros((5, n, 3)),
            U_out=np.zeros((n, 4)),
        )

    def compute(
        self,
        rpy: np.ndarray,
        rpy_rate: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        pos_d: np.ndarray,
        vel_d: np.ndarray,
        acc_d: np.ndarray,
        yaw_d: np.ndarray | float,
        yaw_rate_d: np.ndarray | float = 0.0,
        yaw_acc_d: np.ndarray | float = 0.0,
        wind_force: np.ndarray | None = None,
        omega_body: np.ndarray | None = None,
    ) -> np.ndarray:
        """U1..U4 (n, 4) for all drones (eqs. 17–24).

        rpy, rpy_rate: (n, 3) Euler angles (φ, θ, ψ) and their rates; pos, vel: (n, 3) world;
        pos_d, vel_d, acc_d: (n, 3) reference; yaw_d, yaw_rate_d, yaw_acc_d: (n,) or scalars;
        wind_force: (n, 3) or (3,) known F^w (used when ``wind_feedforward``); omega_body: (n, 3)
        body rates (needed by ``attitude_map="exact"``; without it the paper's map is used).
        """
        n = self.n
        yaw = _per_drone(yaw_d, n)
        yaw_rate = self._zeros1 if isinstance(yaw_rate_d, float) and yaw_rate_d == 0.0 else _per_drone(yaw_rate_d, n)
        yaw_acc = self._zeros1 if isinstance(yaw_acc_d, float) and yaw_acc_d == 0.0 else _per_drone(yaw_acc_d, n)
        use_wind = self.wind_feedforward and wind_force is not None
        wind = _per_drone3(wind_force, n) if use_wind else self._zeros3
        exact = self.attitude_map == "exact" and omega_body is not None
        omega = omega_body if exact else self._zeros3
        first = not self.started
        self.started = True
        c = np.ascontiguousarray  # the inputs as the bound kernel takes them (the same values: the same U)
        f8 = np.float64
        states = (c(rpy, dtype=f8), c(rpy_rate, dtype=f8), c(omega, dtype=f8), c(pos, dtype=f8), c(vel, dtype=f8))
        refs = (c(pos_d, dtype=np.float64), c(vel_d, dtype=np.float64), c(acc_d, dtype=np.float64))
        yaws = (c(yaw), c(yaw_rate), c(yaw_acc))
        args = (self.record, *states, *refs, *yaws, c(wind), use_wind, self.prev_att_d, first, exact, self.att_d)
        kernel = backstepping_kernel
        if all(a.shape == (n, 3) for a in (*states, *refs)):  # else the dispatcher types (and checks) them
            if self._kernel is None:
                self._kernel = bind(backstepping_kernel, *args)
            kernel = self._kernel
        U = kernel(*args)
        self.U = U
        return U


def _per_drone(v, n: int) -> np.ndarray:
    if isinstance(v, np.ndarray) and v.shape == (n,) and v.dtype == np.float64:
        return v
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)))


def _per_drone3(v, n: int) -> np.ndarray:
    if isinstance(v, np.ndarray) and v.shape == (n, 3) and v.dtype == np.float64:
        return v
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=np.float64), (n, 3)))


def _kernel_samples():
    n = 2
    z1, z3, g = np.zeros(n), np.zeros((n, 3)), np.ones((n, 3))
    gains = Gains(
        a_pos=g,
        c1_pos=g,
        c2_pos=g,
        a_att=g,
        c1_att=g,
        c2_att=g,
        drag_over_m=np.ones(3),
        m=0.5,
        g=9.81,
        inertia=np.ones(3),
        torque_scale=np.ones(3),
        cor=np.ones(3),
        L=0.25,
        T=0.01,
    )
    return [
        (
            gains,
            z3.copy(),
            z3,
            z3,
            z3,
            z3,
            z3,
            z3,
            z3,
            z1,
            z1,
            z1,
            z3,
            False,
            np.zeros((n, 2)),
            first,
            exact,
            np.zeros((n, 3)),
        )
        for exact in (True, False)
        for first in (True, False)
    ]


@jit(samples=_kernel_samples)
def backstepping_kernel(
    gains: Gains,
    rpy,
    rpy_rate,
    omega,
    pos,
    vel,
    pos_d,
    vel_d,
    acc_d,
    yaw_d,
    yaw_rate_d,
    yaw_acc_d,
    wind,
    use_wind,
    prev_att_d,
    first,
    exact,
    att_d,
):
    """Eqs. (17)–(24) for n drones; see the module docstring. Writes att_d (n, 3), updates prev_att_d.

    One drone per iteration, with scalar numpy functions: per element the same operations in
    the same order as the array form it replaces (compiled: the same results bit for bit), and
    several times faster for Numba to compile."""
    a_pos, c1_pos, c2_pos, a_att, c1_att, c2_att, drag_over_m, m, g, inertia, torque_scale, cor, L, T = gains
    n = rpy.shape[0]
    U = np.empty((n, 4))
    v = np.empty(3)
    ea1 = np.empty(3)
    ea2 = np.empty(3)
    va = np.empty(3)
    rate_d = np.empty(3)
    Ix, Iy, Iz = inertia[0], inertia[1], inertia[2]
    for i in range(n):
        # ---- position loop (x, y, z): v = ẍ_d + (1 − a²)e1 + (a + b)e2, e2 = ẋ_d + a·e1 − ẋ
        for j in range(3):
            e1 = pos_d[i, j] - pos[i, j]
            e2 = vel_d[i, j] - vel[i, j] + a_pos[i, j] * e1
            v[j] = acc_d[i, j] + c1_pos[i, j] * e1 + c2_pos[i, j] * e2 + drag_over_m[j] * vel[i, j]
            if use_wind:
                v[j] = v[j] - wind[i, j] / m
        cphi = np.cos(rpy[i, 0])
        ctheta = np.cos(rpy[i, 1])
        U1 = np.maximum(m * (v[2] + g) / (cphi * ctheta), U1_FLOOR)  # eq. (18)
        U[i, 0] = U1
        k = m / U1
        Ux = k * v[0]  # eq. (23)
        Uy = k * v[1]  # eq. (24)
        # ---- attitude correction: eqs. (21), (22), clipped (docs/interpretations.md §2)
        s = np.sin(yaw_d[i])
        c = np.cos(yaw_d[i])
        phi_d = np.arcsin(np.minimum(np.maximum(Ux * s - Uy * c, -1.0), 1.0))
        phi_d = np.minimum(np.maximum(phi_d, -MAX_TILT), MAX_TILT)
        theta_d = np.arcsin(np.minimum(np.maximum((Ux * c + Uy * s) / np.cos(phi_d), -1.0), 1.0))
        theta_d = np.minimum(np.maximum(theta_d, -MAX_TILT), MAX_TILT)
        att_d[i, 0] = phi_d
        att_d[i, 1] = theta_d
        att_d[i, 2] = yaw_d[i]
        # desired attitude derivatives (docs/interpretations.md §2): finite difference of φ_d, θ_d over T
        if first:
            rate_d[0] = 0.0
            rate_d[1] = 0.0
        else:
            rate_d[0] = (phi_d - prev_att_d[i, 0]) / T
            rate_d[1] = (theta_d - prev_att_d[i, 1]) / T
        prev_att_d[i, 0] = phi_d
        prev_att_d[i, 1] = theta_d
        rate_d[2] = yaw_rate_d[i]
        # ---- attitude loop (φ, θ, ψ): eqs. (17), (19), (20)
        for j in range(3):
            ea1[j] = att_d[i, j] - rpy[i, j]
        ea1[2] = np.remainder(ea1[2] + np.pi, 2.0 * np.pi) - np.pi
        for j in range(3):
            ea2[j] = rate_d[j] - rpy_rate[i, j] + a_att[i, j] * ea1[j]
            va[j] = c1_att[i, j] * ea1[j] + c2_att[i, j] * ea2[j]
        va[2] += yaw_acc_d[i]
        pd, td, yd = rpy_rate[i, 0], rpy_rate[i, 1], rpy_rate[i, 2]
        if not exact:
            # eq. (1): Euler accelerations = (L/I)·U minus the Coriolis terms (θ̇ψ̇, φ̇ψ̇, φ̇θ̇)
            U[i, 1] = torque_scale[0] * (va[0] - cor[0] * td * yd)
            U[i, 2] = torque_scale[1] * (va[1] - cor[1] * pd * yd)
            U[i, 3] = torque_scale[2] * (va[2] - cor[2] * pd * td)
            continue
        # exact map on the rigid body (see Backstepping): ω̇ = W⁻¹η̈ + (dW⁻¹/dt)η̇, τ = Iω̇ + ω × Iω
        sphi = np.sin(rpy[i, 0])
        sth = np.sin(rpy[i, 1])
        a, b, cc = va[0], va[1], va[2]
        w0 = a - sth * cc - ctheta * td * yd
        w1 = cphi * b + sphi * ctheta * cc - sphi * pd * td + (cphi * ctheta * pd - sphi * sth * td) * yd
        w2 = -sphi * b + cphi * ctheta * cc - cphi * pd * td - (sphi * ctheta * pd + cphi * sth * td) * yd
        p, q, r = omega[i, 0], omega[i, 1], omega[i, 2]
        U[i, 1] = (Ix * w0 + (Iz - Iy) * q * r) / L
        U[i, 2] = (Iy * w1 + (Ix - Iz) * p * r) / L
        U[i, 3] = (Iz * w2 + (Iy - Ix) * p * q) / L
    return U
