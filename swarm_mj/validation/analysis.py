"""The downwash validation against the Neural-Swarm logs (docs/validation.md, "Method").

For each flight: each drone's measured Fa_z (sysid.residual_force_g, smoothed), each model's
prediction of it from the logged states (superposed over every other drone), the passes over
each drone (passes.find_passes); then, per split (calibration / held-out) and per pairing of
vehicles, the pooled RMSE, correlation, and each pass's peak, overall and per vertical-separation bin.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..physics.aero.constants import AIR_DENSITY
from ..physics.aero.downwash import hover_induced_velocity
from ..physics.aero.wake import emitted_state, transport_time, wake_offset
from ..vehicles import Vehicle, load_vehicle
from .flight import DT, MAX_GAP, Flight, find_flights, load_flight, rotation_z_axis
from .params import CALIBRATION, DATASET_MASS_G, DEFAULT_VEHICLE, ValidationParams, delay_alpha
from .passes import Pass, find_passes
from .predict import gym_force, jet_force
from .sysid import (
    G,
    ThrustModel,
    motor_delay,
    read_thrust_model,
    readme_assignments,
    residual_force_g,
    thrust_g,
)

#: The models compared, in table order: ours, gym-pybullet-drones', none.
MODELS = ("jet", "wake", "gym", "none")


def smooth(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over ``window`` samples (shorter at the ends)."""
    if window <= 1:
        return np.asarray(x, float)
    k = np.ones(window)
    return np.convolve(x, k, mode="same") / np.convolve(np.ones(len(x)), k, mode="same")


@dataclass
class DroneSetup:
    """What the validation uses for one drone: its vehicle, thrust model and mass (g)."""

    vehicle: Vehicle
    thrust: ThrustModel
    mass_g: float


@dataclass
class PassResult:
    """One pass's samples (grams-force) and figures."""

    flight: str
    split: str
    pairing: str
    p: Pass
    t: np.ndarray
    measured: np.ndarray
    predicted: dict[str, np.ndarray]

    def peak(self, series: np.ndarray) -> float:
        """The pass's peak: the most negative value (a push down is negative Fa_z)."""
        return float(np.min(series))


@dataclass
class Setup:
    """The run's options: vehicle overrides (drone id → vehicle), mass overrides (g)."""

    vehicles: dict[str, Vehicle] = field(default_factory=dict)
    masses: dict[str, float] = field(default_factory=dict)
    params: ValidationParams = field(default_factory=ValidationParams)


def drone_setup(flight: Flight, drone: str, setup: Setup) -> DroneSetup:
    """The vehicle, thrust model and mass of one drone of a flight: the session's readme.txt names
    its sysid file; the vehicle is the override or the sysid file's default; the mass the override,
    the sysid file's ``mass:`` or the dataset's own (params.DATASET_MASS_G)."""
    where = f"{flight.session / flight.experiment}"
    sysid = readme_assignments(flight.session).get(drone)
    if sysid is None:
        raise UserError(f"{where}: {flight.session / 'readme.txt'} assigns no sysid file to {drone}")
    thrust = read_thrust_model(flight.session / sysid)
    vehicle = setup.vehicles.get(drone)
    if vehicle is None:
        name = DEFAULT_VEHICLE.get(sysid)
        if name is None:
            raise UserError(f"{where}: no vehicle for {drone} (sysid {sysid}); give --vehicle {drone}=NAME_OR_FILE")
        vehicle = load_vehicle(name)
    mass = setup.masses.get(drone, thrust.mass_g if thrust.mass_g is not None else DATASET_MASS_G.get(sysid))
    if mass is None:
        raise UserError(f"{where}: no mass for {drone} (sysid {sysid} gives none); give --mass {drone}=GRAMS")
    return DroneSetup(vehicle, thrust, float(mass))


def split_of(flight: Flight) -> str:
    return "calibration" if (flight.session.name, flight.experiment) in CALIBRATION else "held_out"


#: A model: (flight, setups, produced thrust (gf) per drone, lower index, params) -> force (k, 3) in N.
ModelFn = Callable[[Flight, list[DroneSetup], list[np.ndarray], int, ValidationParams], np.ndarray]


def _jet(flight: Flight, setups: list[DroneSetup], thrust: list[np.ndarray], d: int, p: ValidationParams) -> np.ndarray:
    logs = list(flight.drones.values())
    lo = logs[d]
    f = np.zeros((len(flight.t), 3))
    for j, up in enumerate(logs):
        if j != d:
            f += jet_force(
                up.pos, rotation_z_axis(up.quat), thrust[j] * G / 1000.0, setups[j].vehicle, lo.pos, lo.quat,
                setups[d].vehicle,
            )  # fmt: skip
    return f


def _gym(flight: Flight, setups: list[DroneSetup], thrust: list[np.ndarray], d: int, p: ValidationParams) -> np.ndarray:
    logs = list(flight.drones.values())
    f = np.zeros((len(flight.t), 3))
    for j, up in enumerate(logs):
        if j != d:
            f += gym_force(up.pos, logs[d].pos, setups[j].vehicle.rotor_radius, p.gym_coeffs)
    return f


def _wake(
    flight: Flight, setups: list[DroneSetup], thrust: list[np.ndarray], d: int, p: ValidationParams
) -> np.ndarray:
    """The jet model with a travelling wake (swarm_mj.physics.aero.wake): each upper drone's state taken
    at the time the air now at the lower drone left its rotors (two fixed-point passes on τ)."""
    logs = list(flight.drones.values())
    lo, t = logs[d], flight.t
    f = np.zeros((len(t), 3))
    for j, up in enumerate(logs):
        if j == d:
            continue
        src = setups[j].vehicle
        state = np.concatenate([up.pos, rotation_z_axis(up.quat), thrust[j][:, None] * G / 1000.0], axis=1)
        now = state
        for _ in range(2):
            axis = now[:, 3:6] / np.linalg.norm(now[:, 3:6], axis=1, keepdims=True)
            s = np.einsum("kc,kc->k", lo.pos - now[:, :3], -axis)
            u_h = hover_induced_velocity(now[:, 6], AIR_DENSITY, src.rotor_radius)
            tau = transport_time(s, u_h, 2.0 * src.arm_length)
            now = emitted_state(t, tau, t, state)
        pos = now[:, :3] + wake_offset(t, tau, np.asarray(p.wind))
        f += jet_force(pos, now[:, 3:6], now[:, 6], src, lo.pos, lo.quat, setups[d].vehicle)
    return f


MODEL_FNS: dict[str, ModelFn] = {"jet": _jet, "wake": _wake, "gym": _gym}


#: Fewest free-air samples (1 s) for a log's own offset; a log with fewer takes its flight's.
MIN_FREE_AIR = 100


def free_air(pos: np.ndarray, d: int, valid: np.ndarray, p: ValidationParams) -> np.ndarray:
    """(k,) True where drone d of pos (n, k, 3) is in free air: higher than ``free_air_z_min``, no other
    drone over it (at least ``dz_min`` higher within ``r_window`` horizontally: the passes' "over"), and
    the sample valid."""
    over = np.zeros(pos.shape[1], bool)
    for j in range(pos.shape[0]):
        if j != d:
            rxy = np.linalg.norm(pos[j, :, :2] - pos[d, :, :2], axis=1)
            over |= (pos[j, :, 2] - pos[d, :, 2] >= p.dz_min) & (rxy < p.r_window)
    return (pos[d, :, 2] > p.free_air_z_min) & ~over & valid


def measured(
    flight: Flight, setups: list[DroneSetup], alphas: list[float], p: ValidationParams, offsets: dict | None = None
) -> list[np.ndarray]:
    """Each drone's measured Fa_z (gf, smoothed) less its log's free-air offset (docs/validation.md, "The
    free-air offset"): the median of its Fa_z over its free-air samples (:func:`free_air`); a log with
    fewer than :data:`MIN_FREE_AIR` of them (a drone under another the whole flight) takes the median
    over its flight's other drones' free-air samples, and 0 where there is none. Each log's offset is
    written to ``offsets`` (``"flight/drone"`` → offset, samples, source)."""
    logs = list(flight.drones.values())
    pos = np.stack([g.pos for g in logs])
    meas = [
        smooth(residual_force_g(g, s.thrust, s.mass_g, a)[:, 2], p.smooth_window)
        for g, s, a in zip(logs, setups, alphas, strict=True)
    ]
    if not p.free_air_offset:
        return meas
    air = [free_air(pos, d, flight.valid, p) for d in range(len(logs))]
    out = []
    for d, (name, m) in enumerate(zip(flight.drones, meas, strict=True)):
        n = int(air[d].sum())
        if n >= MIN_FREE_AIR:
            off, src = float(np.median(m[air[d]])), "own"
        else:
            pool = [meas[j][air[j]] for j in range(len(logs)) if j != d and air[j].sum() >= MIN_FREE_AIR]
            off, src = (float(np.median(np.concatenate(pool))), "flight") if pool else (0.0, "none")
        if offsets is not None:
            offsets[f"{flight.name}/{name}"] = {"offset_g": off, "free_air_samples": n, "from": src}
        out.append(m - off)
    return out


def analyse_flight(
    flight: Flight,
    setup: Setup,
    extra: dict[str, ModelFn] | None = None,
    left_out: list[dict] | None = None,
    offsets: dict | None = None,
) -> list[PassResult]:
    """Every pass of one flight with the measured and predicted Fa_z (gf) over it; the events cut by
    the log's ends are described in ``left_out``, each log's free-air offset in ``offsets``."""
    p = setup.params
    names = list(flight.drones)
    logs = list(flight.drones.values())
    setups = [drone_setup(flight, d, setup) for d in names]
    where = f"{flight.session / flight.experiment}"
    alphas = [delay_alpha(p, s.vehicle.motor_tau, DT, f"{where}: {s.vehicle.path}") for s in setups]
    thrust = [motor_delay(thrust_g(s.thrust, g), a) for s, g, a in zip(setups, logs, alphas, strict=True)]
    meas_all = measured(flight, setups, alphas, p, offsets)
    pos = np.stack([g.pos for g in logs])
    fns = dict(MODEL_FNS, **(extra or {}))
    out = []
    for d in range(len(logs)):
        cut: list[tuple[int, int]] = []
        passes = find_passes(pos, d, p.r_pass, p.r_window, p.dz_min, cut)
        if not passes and not cut:
            continue
        meas = meas_all[d]
        pred = {
            m: smooth(fn(flight, setups, thrust, d, p)[:, 2] / G * 1000.0, p.smooth_window) for m, fn in fns.items()
        }
        pred["none"] = np.zeros(len(flight.t))
        for a, b in cut:
            if left_out is None:
                break
            m, j, gy = meas[a:b], pred["jet"][a:b], pred["gym"][a:b]
            left_out.append(
                {
                    "flight": flight.name,
                    "split": split_of(flight),
                    "lower": names[d],
                    "t_s": [round(float(flight.t[a]), 2), round(float(flight.t[b - 1]), 2)],
                    "why": "a drone over it within r_window at the log's start or end (not a pass: it follows)",
                    "mean_measured_g": float(m.mean()),
                    "mean_jet_g": float(j.mean()),
                    "mean_gym_g": float(gy.mean()),
                    "rmse_g": float(np.sqrt(np.mean((m - j) ** 2))),
                    "rmse_gym_g": float(np.sqrt(np.mean((m - gy) ** 2))),
                    "rmse_no_model_g": float(np.sqrt(np.mean(m**2))),
                    "corr": float(np.corrcoef(m, j)[0, 1]),
                }
            )
        for ps in passes:
            sl = slice(ps.start, ps.stop)
            if not flight.valid[sl].all():
                if left_out is not None:
                    t_s = [round(float(flight.t[ps.start]), 2), round(float(flight.t[ps.stop - 1]), 2)]
                    why = f"a gap longer than {MAX_GAP * 1000:.0f} ms in a log during the pass"
                    left_out.append(
                        {"flight": flight.name, "split": split_of(flight), "lower": names[d], "t_s": t_s, "why": why}
                    )
                continue
            pairing = " + ".join(setups[u].vehicle.name for u in ps.uppers) + " over " + setups[d].vehicle.name
            out.append(
                PassResult(
                    flight=flight.name,
                    split=split_of(flight),
                    pairing=pairing,
                    p=ps,
                    t=flight.t[sl],
                    measured=meas[sl],
                    predicted={m: v[sl] for m, v in pred.items()},
                )
            )
    return out


def figures(passes: list[PassResult], models: tuple[str, ...]) -> dict:
    """Pooled figures of a set of passes (gf): RMSE and correlation over their samples, mean
    measured peak, mean peak error (predicted − measured) and the median time by which the
    measured peak follows the predicted one (s), per model."""
    if not passes:
        return {"n_passes": 0}
    m = np.concatenate([q.measured for q in passes])
    peaks = np.array([q.peak(q.measured) for q in passes])
    out: dict = {"n_passes": len(passes), "n_samples": int(m.size), "mean_peak_measured_g": float(peaks.mean())}
    for name in models:
        pr = np.concatenate([q.predicted[name] for q in passes])
        pp = np.array([q.peak(q.predicted[name]) for q in passes])
        key = "" if name == "jet" else f"_{name}"
        rmse = float(np.sqrt(np.mean((m - pr) ** 2)))
        out["rmse_g" if name == "jet" else ("rmse_no_model_g" if name == "none" else f"rmse{key}_g")] = rmse
        if name == "none":
            continue
        out[f"mean_peak_error{key}_g"] = float(np.mean(pp - peaks))
        out[f"corr{key}"] = float(np.corrcoef(m, pr)[0, 1]) if np.std(pr) > 0 and np.std(m) > 0 else None
        lags = [q.t[int(np.argmin(q.measured))] - q.t[int(np.argmin(q.predicted[name]))] for q in passes]
        out[f"peak_lag{key}_s"] = float(np.median(lags))
    return out


def table(passes: list[PassResult], models: tuple[str, ...], bins: tuple[float, ...]) -> dict:
    """:func:`figures` overall and per vertical-separation bin [bins[i], bins[i+1]) (m)."""
    row = figures(passes, models)
    row["bins"] = []
    for lo, hi in zip(bins[:-1], bins[1:], strict=True):
        sel = [q for q in passes if lo <= q.p.dz < hi]
        row["bins"].append({"dz_m": [lo, hi], **figures(sel, models)})
    row["peaks"] = [
        {
            "flight": q.flight,
            "t_s": round(float(q.t[q.p.i_min - q.p.start]), 2),
            "dz_m": q.p.dz,
            "r_min_m": q.p.r_min,
            "measured_g": q.peak(q.measured),
            **{f"{n}_g": q.peak(q.predicted[n]) for n in models if n != "none"},
        }
        for q in passes
    ]
    return row


def load_all(data: Path, progress: Callable[[str], None] | None = None) -> list[Flight]:
    """Every flight under ``data`` (flight.find_flights), decoded. Raises UserError where there is none."""
    if not data.is_dir():
        raise UserError(f"--data {data}: no such folder")
    found = find_flights(data)
    if not found:
        raise UserError(f"--data {data}: no Neural-Swarm logs (files cfNN_RR, two or more drones per flight)")
    flights = []
    for session, exp, run, files in found:
        f = load_flight(session, exp, run, files)
        if progress:
            progress(f"decoded {f.name}: {', '.join(files)}, {f.t[-1] - f.t[0]:.1f} s")
        flights.append(f)
    return flights


def calibrate_gain(passes: list[PassResult]) -> float:
    """Least-squares factor k on the jet model's predictions over the single passes given
    (k = Σ p m / Σ p²): 1 when the upper vehicles' ``downwash_gain`` is the fit on these passes."""
    m = np.concatenate([q.measured for q in passes])
    pr = np.concatenate([q.predicted["jet"] for q in passes])
    return float(np.dot(pr, m) / np.dot(pr, pr))
