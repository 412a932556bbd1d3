"""Neural-Swarm flights: the decoded logs in SI units, on one common 100-Hz time grid (docs/validation.md).

Units of the raw logs (established in docs/validation.md, "Data"): ``tick`` in µs since the log
started; positions in mm, velocities in mm/s, accelerations in mm/s² (world frame, *with* gravity:
the rotated accelerometer reading, ≈ +9810 mm/s² in hover), body rates in mrad/s; the attitude a
compressed quaternion (uint32, :func:`quat_decompress`); PWM 0..65535; battery voltage in mV.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError
from .decode import RawLog, decode

#: Resampling period (s): the logs' nominal 100 Hz (config.txt's "frequency"), the dataset's own grid.
DT = 0.01
#: Longest step (s) between two records that the resampling interpolates across: a few-ms jitter
#: around 10 ms is normal; the logs also have gaps of 40–600 ms (the card writing), marked invalid.
MAX_GAP = 0.025
#: A log file name: the drone's id, an underscore, the flight's number (``cf50_02``).
LOG_NAME = re.compile(r"^(?P<drone>cf\d+)_(?P<run>\d+)$")
_POS = ("x", "y", "z")
_VEL = ("vx", "vy", "vz")
_ACC = ("ax", "ay", "az")
_PWM = ("pwm.m1_pwm", "pwm.m2_pwm", "pwm.m3_pwm", "pwm.m4_pwm")


def quat_decompress(comp: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions (x, y, z, w) from the firmware's 32-bit compressed form (quatcompress.h):
    bits 31–30 the index of the largest component (stored implicitly, positive), then the three
    others from index 3 down to 0, 10 bits each from the least significant end: 9 bits of
    magnitude m (|q_i| = m / 511 / √2) and a sign bit. The largest is √(1 − Σ others²)."""
    c = np.asarray(comp, dtype=np.uint64).reshape(-1)
    largest = (c >> np.uint64(30)).astype(np.int64)
    q = np.zeros((c.size, 4))
    rest = c.copy()
    mask = np.uint64(511)
    for i in range(3, -1, -1):
        here = largest != i
        mag = (rest & mask).astype(float) / 511.0 / math.sqrt(2.0)
        neg = ((rest >> np.uint64(9)) & np.uint64(1)).astype(bool)
        q[here, i] = np.where(neg, -mag, mag)[here]
        rest = np.where(here, rest >> np.uint64(10), rest)
    ss = np.sum(q * q, axis=1)
    q[np.arange(c.size), largest] = np.sqrt(np.maximum(1.0 - ss, 0.0))
    return q


def rotation_z_axis(q: np.ndarray) -> np.ndarray:
    """(n, 3) third column of R(q), the body z axis in the world frame, for q (n, 4) = (x, y, z, w):
    R e3 = (2(xz + yw), 2(yz − xw), 1 − 2(x² + y²)) for a unit quaternion."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)], axis=1)


@dataclass
class DroneLog:
    """One drone's log in SI units at its own sample times ``t`` (s since the log started)."""

    drone: str
    path: Path
    t: np.ndarray  # (k,) s
    pos: np.ndarray  # (k, 3) m
    vel: np.ndarray  # (k, 3) m/s
    acc: np.ndarray  # (k, 3) m/s², world frame, gravity included (specific force rotated to world)
    quat: np.ndarray  # (k, 4) x, y, z, w
    pwm: np.ndarray  # (k, 4) normalised: PWM / 65536
    vbat: np.ndarray  # (k,) V
    crc_errors: int
    #: (k,) False where the sample was interpolated across a gap longer than MAX_GAP; None: all valid.
    valid: np.ndarray | None = None

    @classmethod
    def from_raw(cls, raw: RawLog, drone: str) -> DroneLog:
        """Convert a decoded log (module docstring's units) to SI."""
        need = [f"stateEstimateZ.{k}" for k in (*_POS, *_VEL, *_ACC, "quat")] + ["tick", *_PWM, "pm.vbatMV"]
        missing = [k for k in need if k not in raw.columns]
        if missing:
            raise UserError(f"{raw.path}: the log lacks {', '.join(missing)}")
        if len(raw) < 2:
            raise UserError(f"{raw.path}: the log has fewer than 2 valid records")
        col = raw.columns
        return cls(
            drone=drone,
            path=raw.path,
            t=col["tick"].astype(float) * 1e-6,
            pos=np.stack([col[f"stateEstimateZ.{k}"] for k in _POS], axis=1).astype(float) * 1e-3,
            vel=np.stack([col[f"stateEstimateZ.{k}"] for k in _VEL], axis=1).astype(float) * 1e-3,
            acc=np.stack([col[f"stateEstimateZ.{k}"] for k in _ACC], axis=1).astype(float) * 1e-3,
            quat=quat_decompress(col["stateEstimateZ.quat"]),
            pwm=np.stack([col[k] for k in _PWM], axis=1).astype(float) / 65536.0,
            vbat=col["pm.vbatMV"].astype(float) * 1e-3,
            crc_errors=raw.crc_errors,
        )

    def resample(self, t: np.ndarray) -> DroneLog:
        """This log linearly interpolated at the times t (the dataset's own resampling; quaternions
        component-wise, then normalised)."""

        def lin(a: np.ndarray) -> np.ndarray:
            if a.ndim == 1:
                return np.interp(t, self.t, a)
            return np.stack([np.interp(t, self.t, a[:, c]) for c in range(a.shape[1])], axis=1)

        q = lin(self.quat)
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        right = np.clip(np.searchsorted(self.t, t, side="left"), 0, len(self.t) - 1)  # first record at or after
        left = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1)  # last at or before
        valid = (self.t[right] - self.t[left]) <= MAX_GAP
        return DroneLog(
            drone=self.drone,
            path=self.path,
            t=t,
            pos=lin(self.pos),
            vel=lin(self.vel),
            acc=lin(self.acc),
            quat=q,
            pwm=lin(self.pwm),
            vbat=lin(self.vbat),
            crc_errors=self.crc_errors,
            valid=valid,
        )


@dataclass
class Flight:
    """One flight: every drone's log of one run of one experiment, on a common time grid ``t``
    (every DT from the latest first sample to the earliest last one)."""

    session: Path  # the data collection's folder (holds readme.txt and the sysid files)
    experiment: str  # e.g. "swap_ss"
    run: str  # e.g. "02"
    drones: dict[str, DroneLog]

    @property
    def name(self) -> str:
        return f"{self.session.name}/{self.experiment}/{self.run}"

    @property
    def t(self) -> np.ndarray:
        return next(iter(self.drones.values())).t

    @property
    def valid(self) -> np.ndarray:
        """(k,) True where no drone's log has a gap longer than MAX_GAP."""
        ok = np.ones(len(self.t), bool)
        for g in self.drones.values():
            if g.valid is not None:
                ok &= g.valid
        return ok


def load_flight(session: Path, experiment: str, run: str, files: dict[str, Path]) -> Flight:
    """Decode every drone's log of one flight and resample them onto one common grid (DT)."""
    logs = {d: DroneLog.from_raw(decode(p), d) for d, p in sorted(files.items())}
    t0 = max(float(g.t[0]) for g in logs.values())
    t1 = min(float(g.t[-1]) for g in logs.values())
    if t1 - t0 < 10 * DT:
        raise UserError(f"{session / experiment}: flight {run}: the logs do not overlap in time")
    grid = t0 + DT * np.arange(int(math.floor((t1 - t0) / DT)) + 1)
    return Flight(
        session=session, experiment=experiment, run=run, drones={d: g.resample(grid) for d, g in logs.items()}
    )


def find_flights(data: Path) -> list[tuple[Path, str, str, dict[str, Path]]]:
    """Every flight under ``data``: (session folder, experiment, run, {drone: log path}), a flight being
    the logs ``<drone>_<run>`` of one experiment folder (a folder with such files) sharing a run
    number. ``data`` may be the dataset's root, a session or an experiment folder."""
    found: dict[tuple[Path, str], dict[str, dict[str, Path]]] = {}
    for p in sorted(data.rglob("cf*_*")):
        m = LOG_NAME.match(p.name)
        if not m or not p.is_file():
            continue
        key = (p.parent.parent, p.parent.name)
        found.setdefault(key, {}).setdefault(m["run"], {})[m["drone"]] = p
    out = []
    for (session, exp), runs in sorted(found.items(), key=lambda kv: (str(kv[0][0]), kv[0][1])):
        for run, files in sorted(runs.items()):
            if len(files) >= 2:
                out.append((session, exp, run, files))
    return out
