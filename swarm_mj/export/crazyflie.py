"""``swarm-mj export crazyflie``: a flown scenario as the Crazyflie's uploaded pieces (docs/export.md).

The scenario is flown (:func:`swarm_mj.experiments.runner.run`); each drone's **flown** path over
[--from, --to], sampled at the control period, is fitted by degree-7 pieces joined up to the third
derivative (:mod:`.poly`); the pieces are checked (:mod:`.checks`) and, only when every check passes,
written to a folder at once (a temporary folder renamed into place):

* ``<drone>.csv``: the pieces in Crazyswarm's ``uav_trajectories`` format (:data:`CSV_HEADER`), float32
  values written so that they read back exactly;
* ``path.csv``: the fitted path (``t, drone, x, y, z, yaw``, one row per drone and sample);
* ``manifest.json``: the drones, their starts, the keep-out, the time span, the vehicle and every check;
* ``upload.py``: the cflib script (:mod:`.upload`);
* ``scenario.toml``: what ``swarm-mj run DIR`` flies the set back with (:mod:`.flyback`).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import struct
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SimulationDiverged, UserError
from ..output.atomic import dumps_strict
from ..scenario import Scenario, parse_scenario, scenario_toml
from . import upload as upload_template
from .checks import BYTES_PER_PIECE, Check, Limits, failures, run_checks
from .poly import Pieces, fit_adaptive

#: Crazyswarm's ``uav_trajectories`` header (whoenig/uav_trajectories ``genTrajectory.cpp``).
CSV_HEADER = "Duration," + ",".join(f"{a}^{j}" for a in ("x", "y", "z", "yaw") for j in range(8))
#: The manifest's ``format``: what ``swarm-mj run DIR`` recognises.
FORMAT = "swarm-mj export crazyflie"
FORMAT_VERSION = 1
#: Files of a set (besides one CSV per drone).
MANIFEST, PATH_CSV, UPLOAD, SCENARIO = "manifest.json", "path.csv", "upload.py", "scenario.toml"
#: The fit aims at this share of the tolerance (the rest is left to float32 rounding).
FIT_TARGET = 0.9


def pack(pieces: Pieces) -> bytes:
    """The pieces as the commander's memory holds them: per piece, x, y, z and yaw's 8 float32
    coefficients, then the float32 duration, little-endian (cflib ``Poly4D.pack``)."""
    p = pieces.as_float32()
    out = bytearray()
    for c, d in zip(p.coeffs, p.durations):
        out += struct.pack("<32f", *c.reshape(-1).tolist()) + struct.pack("<f", float(d))
    assert len(out) == BYTES_PER_PIECE * p.n_pieces
    return bytes(out)


def _f32(v: float) -> str:
    """A float32 as text that reads back to the same float32 (9 significant digits)."""
    return f"{float(np.float32(v)):.9g}"


def csv_text(pieces: Pieces) -> str:
    """The pieces in the ``uav_trajectories`` CSV format: one row per piece, the duration then x^0..x^7,
    y^0..y^7, z^0..z^7, yaw^0..yaw^7."""
    p = pieces.as_float32()
    rows = [CSV_HEADER]
    for c, d in zip(p.coeffs, p.durations):
        rows.append(",".join([_f32(d)] + [_f32(v) for v in c.reshape(-1)]))
    return "\n".join(rows) + "\n"


def read_csv(path: Path) -> Pieces:
    """Pieces from a ``uav_trajectories`` CSV (:class:`UserError` naming the file for anything else)."""
    try:
        lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read: {exc}", where=str(path)) from None
    if not lines or lines[0].strip().replace(" ", "").lower() != CSV_HEADER.lower():
        raise UserError(f"not a uav_trajectories CSV (the header must be {CSV_HEADER[:30]}...)", where=str(path))
    try:
        rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=np.float64)
    except ValueError as exc:
        raise UserError(f"a value is not a number ({exc})", where=str(path)) from None
    if rows.ndim != 2 or rows.shape[0] == 0 or rows.shape[1] != 33:
        raise UserError("needs at least one row of 33 numbers (a duration and 32 coefficients)", where=str(path))
    if not np.isfinite(rows).all() or (rows[:, 0] <= 0).any():
        raise UserError("every number must be finite and every duration positive", where=str(path))
    return Pieces(durations=rows[:, 0].astype(np.float32), coeffs=rows[:, 1:].reshape(-1, 4, 8).astype(np.float32))


@dataclass(frozen=True)
class Sampled:
    """The path fitted: plan times t (k,) from 0, positions pos (k, n, 3) as flown, yaw (k, n) as
    commanded (unwrapped), and the velocities (n, 4) of x, y, z, yaw at both ends."""

    names: list[str]
    t0: float  # the scenario's time of the plan's start (s)
    t: np.ndarray
    pos: np.ndarray
    yaw: np.ndarray
    v0: np.ndarray
    v1: np.ndarray


def sample_path(log, k0: int, k1: int) -> Sampled:  # noqa: ANN001 - a RunLog
    """Samples k0..k1 of a run's log: the flown positions and velocities, and the commanded yaw ψ_d (the
    flown yaw is the controller's error around it, not a plan: docs/export.md, "What is fitted")."""
    t = log.t[k0 : k1 + 1]
    yaw = np.unwrap(log.att_d[:, :, 2], axis=0)  # (k, n)
    rate = np.gradient(yaw, log.t, axis=0) if len(log.t) > 1 else np.zeros_like(yaw)
    ends = [np.column_stack([log.vel[k], rate[k]]) for k in (k0, k1)]
    return Sampled(
        names=list(log.names), t0=float(t[0]), t=t - t[0], pos=log.pos[k0 : k1 + 1].copy(),
        yaw=yaw[k0 : k1 + 1].copy(), v0=ends[0], v1=ends[1],
    )  # fmt: skip


def fit_drones(path: Sampled, limits: Limits) -> tuple[list[Pieces], Check | None]:
    """Each drone's pieces (:func:`~.poly.fit_adaptive`), or the failed ``pieces`` check of the first drone
    that needs more than the memory holds to stay within the tolerance."""
    tol = np.array([limits.tolerance_m, limits.yaw_tolerance_rad])
    groups = [slice(0, 3), slice(3, 4)]
    out: list[Pieces] = []
    for i, name in enumerate(path.names):
        y = np.column_stack([path.pos[:, i], path.yaw[:, i]])
        p = fit_adaptive(path.t, y, path.v0[i], path.v1[i], tol, groups, limits.max_pieces, FIT_TARGET)
        if p is None:
            return out, Check(
                name="pieces", passed=False, value=float("inf"), limit=float(limits.max_pieces), unit="", drone=name,
                text=f"{name} needs more than {limits.max_pieces} pieces ({limits.memory_bytes} bytes) to stay within "
                f"{limits.tolerance_m * 100:g} cm of its {path.t[-1]:.1f}-s path: shorten it (--from, --to)",
            )  # fmt: skip
        out.append(p)
    return out, None


def check_output_folder(out: str | Path) -> Path:
    """``-o DIR`` before anything flies: absent, an empty folder or an earlier set (its manifest names
    :data:`FORMAT`), in a writable folder (:class:`UserError` otherwise)."""
    p = Path(out)
    if not str(out).strip():
        raise UserError("-o: an empty folder name")
    if p.exists():
        if not p.is_dir():
            raise UserError(f"-o {out}: exists and is not a folder")
        if any(p.iterdir()) and not _is_set(p):
            raise UserError(f"-o {out}: a folder that is neither empty nor an exported set; give a new one")
    parent = p.resolve().parent
    if not parent.is_dir():
        raise UserError(f"-o {out}: folder {p.parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"-o {out}: folder {p.parent} is not writable")
    return p


def _is_set(p: Path) -> bool:
    try:
        import json

        return json.loads((p / MANIFEST).read_text()).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def write_set(out: Path, files: dict[str, str]) -> None:
    """The files into a temporary folder beside ``out``, then renamed into place at once (an earlier set
    at ``out`` is replaced, moved aside first and removed after)."""
    out = Path(out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.resolve().parent))
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o777 & ~umask)  # a folder as mkdir makes it (mkdtemp's is private)
        for name, text in files.items():
            (tmp / name).write_text(text)
        os.chmod(tmp / UPLOAD, 0o755)
        old = None
        if out.exists():
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            os.replace(out, old)
        os.replace(tmp, out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        from ..errors import OutputError

        raise OutputError(f"cannot write {out}: {exc.strerror or exc}") from None


def path_csv(path: Sampled) -> str:
    rows = ["t,drone,x,y,z,yaw"]
    for k, t in enumerate(path.t):
        for i, name in enumerate(path.names):
            x, y, z = path.pos[k, i]
            rows.append(f"{t:.6f},{name},{x:.9g},{y:.9g},{z:.9g},{path.yaw[k, i]:.9g}")
    return "\n".join(rows) + "\n"


def flyback_toml(sc: Scenario, path: Sampled) -> str:
    """The scenario ``swarm-mj run DIR`` flies the set back with: the flown scenario's vehicle, gains (inline),
    physics, wind, seed, control period and D schedule (shifted to the plan's start), every drone starting
    at rest at its start, the anti-collision off (the plan was checked against the keep-out; ``--anti-collision``
    turns one on) and the leader's trajectory a hover at its start: ``swarm-mj run DIR`` replaces every
    drone's reference by its pieces (:mod:`.flyback`)."""
    raw = {k: v for k, v in (sc.raw if isinstance(sc.raw, dict) else {}).items()}
    t0, dur = path.t0, float(path.t[-1])
    starts = path.pos[0]
    raw["name"] = f"{sc.name}_export"
    raw["description"] = f"{sc.name} exported from {t0:g} s to {t0 + dur:g} s, flown back from its pieces"
    raw["duration"] = round(dur / sc.control_period) * sc.control_period
    raw["steady_after"] = max(float(sc.steady_after) - t0, 0.0)
    raw["vehicle"] = {"model": _vehicle_model(sc)}
    yaw_deg = float(np.rad2deg(path.yaw[0, 0]))
    raw["leader"] = {"trajectory": "hover", "start": starts[0].tolist(),
                     "params": {"position": starts[0].tolist(), "yaw_deg": yaw_deg}}  # fmt: skip
    if sc.n_followers:
        raw["followers"] = {"start": starts[1:].tolist()}
    else:
        raw.pop("followers", None)
    form = dict(raw.get("formation", {}) or {})
    form["anti_collision"] = "off"
    form["diameter"] = _shifted_diameter(sc, t0)
    raw["formation"] = form
    ctl = dict(raw.get("controller", {}) or {})
    ctl["gains"] = np.asarray(sc.gains, dtype=float).tolist()
    raw["controller"] = ctl
    raw["aero"] = {**(raw.get("aero") or {}), "model": sc.aero.model}
    head = "# written by swarm-mj export crazyflie: `swarm-mj run THIS_FOLDER` flies each drone on its pieces\n"
    return head + scenario_toml(raw)


def _vehicle_model(sc: Scenario) -> str:
    """The scenario's vehicle as a document names it from anywhere: a bundled name or an absolute path."""
    from ..vehicles import bundled

    if sc.vehicle in bundled():
        return sc.vehicle
    p = Path(sc.vehicle)
    if not p.is_absolute() and sc.path and not sc.path.startswith("<"):
        p = Path(sc.path).parent / p
    return str(p.resolve())


def _shifted_diameter(sc: Scenario, t0: float) -> float | list[list[float]]:
    """The D schedule from the plan's start: D(t0) at 0, then the later changes shifted by t0."""
    d = sc.diameter
    if not isinstance(d, list):
        return float(d)
    at0 = float(np.asarray(sc.diameter_schedule()(np.array([t0]))).reshape(-1)[0])
    later = [[float(t) - t0, float(v)] for t, v in d if float(t) > t0]
    return [[0.0, at0]] + later


def manifest(sc: Scenario, path: Sampled, pieces: list[Pieces], checks: list[Check], radii: np.ndarray) -> dict:
    """The set's description (docs/export.md, "manifest.json")."""
    dur = float(path.t[-1])
    drones = []
    for i, (name, p) in enumerate(zip(path.names, pieces)):
        drones.append({
            "name": name, "csv": f"{name}.csv", "start": path.pos[0, i].tolist(),
            "start_yaw_rad": float(path.yaw[0, i]), "pieces": p.n_pieces, "bytes": p.n_pieces * BYTES_PER_PIECE,
            "duration_s": p.duration,
        })  # fmt: skip
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "scenario": sc.name,
        "scenario_file": sc.path,
        "vehicle": sc.vehicle,
        "vehicle_params": {
            "mass_kg": sc.params.m,
            "max_thrust_per_rotor_n": sc.params.f_max,
            "drag_n_s_per_m": sc.params.drag.tolist(),
        },  # fmt: skip
        "physics": sc.aero.model,
        "anti_collision": sc.rule,
        "seed": sc.seed,
        "fitted": "the flown path (positions) and the commanded yaw, at the control period",
        "time_span_s": [path.t0, path.t0 + dur],
        "duration_s": dur,
        "control_period_s": sc.control_period,
        "units": {"position": "m", "yaw": "rad", "time": "s from the plan's start"},
        "keepout_radii_m": np.asarray(radii).tolist(),
        "airborne_m": 0.1,
        "drones": drones,
        "checks": {c.name: c.to_dict() for c in checks},
        "files": {
            "pieces": "<drone>.csv (uav_trajectories)",
            "path": PATH_CSV,
            "upload": UPLOAD,
            "flyback": SCENARIO,
        },  # fmt: skip
    }


def cflib_note() -> str | None:
    """A line saying that ``upload.py`` needs cflib, where it is not installed (None where it is)."""
    if importlib.util.find_spec("cflib") is not None:
        return None
    return "upload.py needs cflib: pip install 'swarm-mj[crazyflie]' (or pip install cflib)"


#: A drone has formed when it stays this close to its reference (m): the summary's settling band.
FORMED_M = 0.05


def default_from(log, k1: int) -> float:  # noqa: ANN001 - a RunLog
    """The plan's start when ``--from`` is not given: the first sample from which every drone stays within
    :data:`FORMED_M` of its reference (the leader its commanded position, each follower its slot, in 3D) until
    sample k1, the swarm formed (docs/export.md, "Where the plan starts"). :class:`UserError` when it never
    is before then."""
    ref = log.slot[: k1 + 1].copy()
    ref[:, 0] = log.pos_d[: k1 + 1, 0]
    far = (np.linalg.norm(log.pos[: k1 + 1] - ref, axis=-1) > FORMED_M).any(axis=1)  # (k,)
    k = int(np.flatnonzero(far)[-1]) + 1 if far.any() else 0
    if k >= k1:
        raise UserError(
            f"--from: the swarm has not formed (every drone within {FORMED_M * 100:g} cm of its slot) by --to "
            f"{log.t[k1]:g} s; give --from (0: the whole flight, take-off included)"
        )
    return float(log.t[k])


def export_crazyflie(sc: Scenario, out: Path, t_from: float | None, t_to: float, *, progress: bool | None = None,
                     limits: Limits = Limits()) -> tuple[dict, list[Check]]:  # fmt: skip
    """Fly ``sc`` to ``t_to``, fit, check, and write the set to ``out`` only when every check passes; returns the
    manifest and the checks. Raises :class:`UserError` (one line naming the failed checks) otherwise, having
    written nothing."""
    from ..experiments.runner import run
    from ..formation.barrier import keepout_radii

    result = run(sc, duration=t_to, progress=progress)
    if isinstance(result.error, KeyboardInterrupt):
        raise result.error
    if result.error is not None:
        raise SimulationDiverged(f"the flight to export stopped: {result.error}; nothing written")
    T = sc.control_period
    k1 = min(round(t_to / T), len(result.log.t) - 1)
    t0 = default_from(result.log, k1) if t_from is None else float(t_from)
    path = sample_path(result.log, round(t0 / T), k1)
    pieces, failed = fit_drones(path, limits)
    if failed is not None:
        raise UserError(f"export refused, nothing written: pieces: {failed.text}")
    checks = run_checks(pieces, path.names, path.t, path.pos, path.yaw, sc.params, T, limits)
    flight = result.summary.get("flight") or {}
    if not flight.get("ok", True):
        from ..experiments.outcome import failure_line

        checks.append(Check(name="flight", passed=False, value=0.0, limit=0.0, unit="", text=str(failure_line(flight))))
    line = failures(checks)
    if line is not None:
        raise UserError(f"export refused, nothing written: {line}")
    radii = keepout_radii(sc.params, rotor_radius=sc.params.rotor_radius)
    man = manifest(sc, path, pieces, checks, radii)
    files = {f"{n}.csv": csv_text(p) for n, p in zip(path.names, pieces)}
    files |= {PATH_CSV: path_csv(path), MANIFEST: dumps_strict(man) + "\n", SCENARIO: flyback_toml(sc, path),
              UPLOAD: Path(upload_template.__file__).read_text()}  # fmt: skip
    try:  # what `swarm-mj run DIR` will read (e.g. starts closer than the vehicle's clearance) is refused now
        parse_scenario(tomllib.loads(files[SCENARIO]), str(out / SCENARIO))
    except UserError as exc:
        raise UserError(f"export refused, nothing written: flight back: {exc}") from None
    write_set(out, files)
    return man, checks
