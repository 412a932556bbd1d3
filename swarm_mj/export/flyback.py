"""An exported set flown back in the simulator: ``swarm-mj run DIR`` (docs/export.md, "Flown back").

:func:`load_export` reads a set written by ``swarm-mj export crazyflie``: its manifest, each drone's
``uav_trajectories`` CSV and its ``scenario.toml`` (the vehicle, gains, physics, wind, starts; the
anti-collision off). :class:`PiecesPolicy` is the backstepping policy of every run whose references are
each drone's own pieces, evaluated as the Crazyflie's commander does (position, velocity and acceleration
of the piece that holds t; after the end, the last point held with zero velocity and acceleration): it
writes them into the observation's setpoint before the rule and the controller read it, so the run's log
and summary (its RMSE, keep-out, contacts) are measured against the pieces.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..control.policy import BacksteppingPolicy
from ..errors import UserError
from ..physics.params import QuadParams
from ..scenario import Scenario, parse_scenario
from .crazyflie import FORMAT, MANIFEST, SCENARIO, read_csv
from .poly import Pieces, derivative_coeffs, horner

#: The tracking band the flight back reports the time into (m): the export's tolerance.
WITHIN_M = 0.01


class PiecesReference:
    """Every drone's pieces evaluated at once: :meth:`__call__` (t) → pos, vel, acc (n, 3) and yaw (n,)."""

    def __init__(self, pieces: list[Pieces]) -> None:
        n, m = len(pieces), max(p.n_pieces for p in pieces)
        self.n_pieces = np.array([p.n_pieces for p in pieces])
        self.knots = np.full((n, m + 1), np.inf)  # (n, m + 1), padded with +inf
        self.coeffs = np.zeros((n, m, 4, 8))
        for i, p in enumerate(pieces):
            self.knots[i, : p.n_pieces + 1] = p.knots
            self.coeffs[i, : p.n_pieces] = np.asarray(p.coeffs, dtype=np.float64)
        self.end = self.knots[np.arange(n), self.n_pieces]  # (n,)
        self._d = [derivative_coeffs(self.coeffs, r) for r in range(3)]

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = len(self.end)
        tc = np.minimum(max(float(t), 0.0), self.end)  # (n,) clamped to each drone's end
        i = np.minimum((self.knots[:, 1:] < tc[:, None]).sum(axis=1), self.n_pieces - 1)  # piece holding tc
        tau = tc - self.knots[np.arange(n), i]
        rows = np.arange(n)
        pos, vel, acc = (horner(d[rows, i], tau) for d in self._d)  # (n, 4) each
        over = float(t) > self.end  # the commander holds the last point, at rest
        vel[over], acc[over] = 0.0, 0.0
        return pos[:, :3], vel[:, :3], acc[:, :3], pos[:, 3]


class PiecesPolicy(BacksteppingPolicy):
    """:class:`~swarm_mj.control.policy.BacksteppingPolicy` with each drone's reference its own pieces."""

    #: why the chunk driver cannot fly it (``swarm_mj.experiments.runner.run``): the references come from Python
    not_compiled = "each drone's reference is its own pieces (an exported set), set in Python"

    def __init__(self, scenario: Scenario, params: QuadParams, *, pieces: list[Pieces], **kw: Any) -> None:
        super().__init__(scenario, params, **kw)
        if len(pieces) != self.n:
            raise UserError(f"{len(pieces)} drones' pieces for {self.n} drones")
        self.reference = PiecesReference(pieces)

    def references(self, obs: dict) -> tuple[Any, Any, Any]:
        pos, vel, acc, yaw = self.reference(float(obs["time"]))
        # in place: the observation's own arrays, which the run's log reads as each drone's reference
        obs["setpoint"][...] = pos
        obs["setpoint_vel"][...] = vel
        obs["setpoint_acc"][...] = acc
        obs["setpoint_yaw"][...] = yaw
        return super().references(obs)


@dataclass(frozen=True)
class ExportSet:
    """A set read back: its folder, manifest, the scenario it is flown with and each drone's pieces."""

    folder: Path
    manifest: dict
    scenario: Scenario
    pieces: list[Pieces]

    def policy(self, scenario: Scenario, params: QuadParams) -> PiecesPolicy:
        """The policy ``swarm_mj.experiments.runner.run`` flies (its ``policy`` argument)."""
        return PiecesPolicy(scenario, params, pieces=self.pieces)

    def tracking(self, log: Any) -> dict:
        """How closely the drones flew their pieces: the largest 3D distance to the reference and its RMS over
        drones and samples, and where the largest was (the log's ``pos_d`` is the pieces' position)."""
        e = np.linalg.norm(log.pos - log.pos_d, axis=-1)  # (k, n)
        k, i = np.unravel_index(int(np.nanargmax(e)), e.shape)
        return {
            "tracking_error_max_m": float(e[k, i]),
            "tracking_error_rms_m": float(np.sqrt(np.nanmean(e**2))),
            "worst_drone": log.names[i],
            "worst_at_s": float(log.t[k]),
            "within_1cm_from_s": _within_from(log.t, e, WITHIN_M),
            "pieces": {d["name"]: d["pieces"] for d in self.manifest["drones"]},
        }

    def line(self, summary: dict) -> str:
        """One line for ``swarm-mj run DIR``."""
        tr = summary["export"]
        since = tr["within_1cm_from_s"]
        return (
            f"exported set {self.folder}: the drones flew their pieces within "
            f"{tr['tracking_error_max_m'] * 100:.2f} cm "
            f"({tr['worst_drone']} at {tr['worst_at_s']:.2f} s; RMS {tr['tracking_error_rms_m'] * 100:.2f} cm), "
            + (f"within 1 cm from {since:.2f} s" if since is not None else "not within 1 cm by the end")
        )


def _within_from(t: np.ndarray, e: np.ndarray, band: float) -> float | None:
    """The time (s) from which every error e (k, n) stays within ``band``; None when not by the end."""
    far = np.flatnonzero((e > band).any(axis=1))
    if not len(far):
        return 0.0
    return float(t[far[-1] + 1]) if far[-1] + 1 < len(t) else None


def is_export(path: str | Path) -> bool:
    """Whether ``path`` is a folder (``swarm-mj run`` then reads it as an exported set)."""
    return Path(path).is_dir()


def load_export(folder: str | Path) -> ExportSet:
    """Read a set written by ``swarm-mj export crazyflie`` (:class:`UserError` naming the file otherwise)."""
    d = Path(folder)
    mpath = d / MANIFEST
    try:
        man = json.loads(mpath.read_text())
    except FileNotFoundError:
        raise UserError(
            f"a folder without {MANIFEST}: not an exported set (swarm-mj export crazyflie)", where=str(d)
        ) from None
    except (OSError, ValueError) as exc:
        raise UserError(f"cannot read: {exc}", where=str(mpath)) from None
    if not isinstance(man, dict) or man.get("format") != FORMAT or not isinstance(man.get("drones"), list):
        raise UserError(f"not a manifest of {FORMAT!r}", where=str(mpath))
    spath = d / SCENARIO
    try:
        data = tomllib.loads(spath.read_text())
    except FileNotFoundError:
        raise UserError("missing: the set's flight-back scenario", where=str(spath)) from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"cannot read: {exc}", where=str(spath)) from None
    sc = parse_scenario(data, str(spath), name=str(data.get("name", d.name)))
    names = [str(x.get("name")) if isinstance(x, dict) else "?" for x in man["drones"]]
    if names != sc.names:
        raise UserError(f"the manifest's drones {names} are not the scenario's {sc.names}", where=str(mpath))
    pieces = []
    for x in man["drones"]:
        csv = x.get("csv")
        if not isinstance(csv, str) or Path(csv).name != csv:
            raise UserError(f"drone {x.get('name')}: csv must be a file name in the folder", where=str(mpath))
        pieces.append(read_csv(d / csv))
    return ExportSet(folder=d, manifest=man, scenario=sc, pieces=pieces)
