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
    Ux = m/U1 (v_x + Kx ẋ/m − F^w_x/m)                    (23, SPEC §2: F^w/m, not F^w/Ix)
    Uy = m/U1 (v_y + Ky ẏ/m − F^w_y/m)                    (24)
    φ_d = asin(Ux sin ψ_d − Uy cos ψ_d)                   (21)
    θ_d = asin((Ux cos ψ_d + Uy sin ψ_d)/cos φ_d)         (22)

φ_d and θ_d are clipped to ±45°, the asin arguments to [−1, 1], U1 has a small
positive floor (SPEC §2). The desired-attitude derivatives that the paper leaves
out are finite differences of the commanded φ_d, θ_d over the control period T
(SPEC §2); ψ_d and its derivatives come from the reference.

The state is read from MuJoCo: φ, θ, ψ from the quaternion and φ̇, θ̇, ψ̇ from the
body angular velocity, see :mod:`swarm_mj.state`.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..params import DEFAULT_PARAMS, QuadParams
from ..state import wrap_angle

#: Paper Table 4: α1..α12 (roll, pitch, yaw, x, y, z pairs).
TABLE4_GAINS = np.array([4.4025, 9.3048, 6.4184, 5.0494, 7.6955, 2.2141,
                         4.8548, 7.0579, 4.4025, 6.6385, 6.1893, 3.5344])
MAX_TILT = np.deg2rad(45.0)
U1_FLOOR = 0.05  # N


def load_gains(path: str | Path) -> np.ndarray:
    """Read a gains TOML file (``gains = [12 floats]``, as written by ``swarm-mj tune``)."""
    path = Path(path)
    if not path.exists():
        raise UserError("gains file not found", where=str(path))
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"not valid TOML: {exc}", where=str(path)) from None
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

    def __init__(self, n: int, gains: np.ndarray | None = None, *, params: QuadParams = DEFAULT_PARAMS,
                 control_period: float = 0.01, wind_feedforward: bool = True,
                 attitude_map: str = "exact") -> None:
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
        self._a2_att, self._a2_pos = self._a_att ** 2, self._a_pos ** 2
        p = params
        self._inertia = np.array([p.Ix, p.Iy, p.Iz])
        # Coriolis coefficients of eqs. (17), (19), (20).
        self._cor = np.array([(p.Iy - p.Iz) / p.Ix, (p.Iz - p.Ix) / p.Iy, (p.Ix - p.Iy) / p.Iz])
        self._torque_scale = self._inertia / p.L
        self._drag_over_m = p.drag / p.m
        self.reset()

    def reset(self) -> None:
        """Forget the finite-difference history of the commanded attitude."""
        self._prev_att_d: np.ndarray | None = None   # (n, 2) previous (φ_d, θ_d)
        self.att_d = np.zeros((self.n, 3))           # (n, 3) last commanded (φ_d, θ_d, ψ_d)
        self.U = np.zeros((self.n, 4))               # (n, 4) last output

    def compute(self, rpy: np.ndarray, rpy_rate: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                pos_d: np.ndarray, vel_d: np.ndarray, acc_d: np.ndarray,
                yaw_d: np.ndarray, yaw_rate_d: np.ndarray | float = 0.0, yaw_acc_d: np.ndarray | float = 0.0,
                wind_force: np.ndarray | None = None, omega_body: np.ndarray | None = None) -> np.ndarray:
        """U1..U4 (n, 4) for all drones.

        rpy, rpy_rate: (n, 3) Euler angles (φ, θ, ψ) and their rates; pos, vel: (n, 3) world;
        pos_d, vel_d, acc_d: (n, 3) reference; yaw_d (n,) or scalar; wind_force: (n, 3) or (3,) known F^w.
        """
        p = self.params
        # ---- position loop (x, y, z): eqs. (18), (23), (24)
        e1 = pos_d - pos
        e2 = vel_d + self._a_pos * e1 - vel
        v = acc_d + e1 + self._a_pos * e2 - self._a2_pos * e1 + self._b_pos * e2
        v += self._drag_over_m * vel
        if self.wind_feedforward and wind_force is not None:
            v -= wind_force / p.m
        cphi, ctheta = np.cos(rpy[:, 0]), np.cos(rpy[:, 1])
        U1 = p.m * (v[:, 2] + p.g) / (cphi * ctheta)
        np.maximum(U1, U1_FLOOR, out=U1)
        k = p.m / U1
        Ux, Uy = k * v[:, 0], k * v[:, 1]
        # ---- attitude correction: eqs. (21), (22)
        psi_d = np.broadcast_to(yaw_d, (self.n,))
        s, c = np.sin(psi_d), np.cos(psi_d)
        phi_d = np.arcsin(np.clip(Ux * s - Uy * c, -1.0, 1.0))
        np.clip(phi_d, -MAX_TILT, MAX_TILT, out=phi_d)
        theta_d = np.arcsin(np.clip((Ux * c + Uy * s) / np.cos(phi_d), -1.0, 1.0))
        np.clip(theta_d, -MAX_TILT, MAX_TILT, out=theta_d)
        att_d = self.att_d
        att_d[:, 0], att_d[:, 1], att_d[:, 2] = phi_d, theta_d, psi_d
        # desired attitude derivatives (SPEC §2): finite difference over T for φ_d, θ_d
        att_rate_d = np.empty((self.n, 3))
        if self._prev_att_d is None:
            att_rate_d[:, :2] = 0.0
            self._prev_att_d = att_d[:, :2].copy()
        else:
            np.subtract(att_d[:, :2], self._prev_att_d, out=att_rate_d[:, :2])
            att_rate_d[:, :2] /= self.T
            self._prev_att_d[:] = att_d[:, :2]
        att_rate_d[:, 2] = yaw_rate_d
        # ---- attitude loop (φ, θ, ψ): eqs. (17), (19), (20)
        ea1 = att_d - rpy
        ea1[:, 2] = wrap_angle(ea1[:, 2])
        ea2 = att_rate_d + self._a_att * ea1 - rpy_rate
        va = ea1 + self._a_att * ea2 - self._a2_att * ea1 + self._b_att * ea2
        va[:, 2] += yaw_acc_d
        U = np.empty((self.n, 4))
        U[:, 0] = U1
        if self.attitude_map == "paper" or omega_body is None:
            # eq. (1): Euler-angle accelerations = L/I·U minus the Coriolis terms (θ̇ψ̇, φ̇ψ̇, φ̇θ̇)
            r = rpy_rate
            va[:, 0] -= self._cor[0] * r[:, 1] * r[:, 2]
            va[:, 1] -= self._cor[1] * r[:, 0] * r[:, 2]
            va[:, 2] -= self._cor[2] * r[:, 0] * r[:, 1]
            np.multiply(va, self._torque_scale, out=U[:, 1:4])
        else:
            U[:, 1:4] = self._exact_torque(rpy, rpy_rate, omega_body, va)
        return U

    def _exact_torque(self, rpy: np.ndarray, rpy_rate: np.ndarray, omega: np.ndarray,
                      eta_dd: np.ndarray) -> np.ndarray:
        """Body torques / L (n, 3) that give the Euler-angle accelerations ``eta_dd`` on the rigid body.

        Eq. (1) treats (φ̈, θ̈, ψ̈) as (L/I)·U minus approximate Coriolis terms, which holds
        near hover only. MuJoCo integrates the exact Newton–Euler equations, so here the
        commanded Euler accelerations are mapped exactly: ω = W⁻¹η̇, ω̇ = W⁻¹η̈ + (dW⁻¹/dt)η̇,
        τ = I·ω̇ + ω × (I·ω), U = τ / L. Near hover this equals the paper's map.
        """
        sphi, cphi = np.sin(rpy[:, 0]), np.cos(rpy[:, 0])
        sth, cth = np.sin(rpy[:, 1]), np.cos(rpy[:, 1])
        pd, td, yd = rpy_rate[:, 0], rpy_rate[:, 1], rpy_rate[:, 2]
        a, b, c = eta_dd[:, 0], eta_dd[:, 1], eta_dd[:, 2]
        wd = np.empty_like(eta_dd)
        wd[:, 0] = a - sth * c - cth * td * yd
        wd[:, 1] = cphi * b + sphi * cth * c - sphi * pd * td + (cphi * cth * pd - sphi * sth * td) * yd
        wd[:, 2] = -sphi * b + cphi * cth * c - cphi * pd * td - (sphi * cth * pd + cphi * sth * td) * yd
        I = self._inertia
        Iw = omega * I
        tau = wd * I + np.cross(omega, Iw)
        return tau / self.params.L
