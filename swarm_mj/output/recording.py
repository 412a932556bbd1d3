"""Rerun recordings (``.rrd``) of a run, logged in batches with ``send_columns`` (docs/design.md, "the rooms").

Entities, on the ``sim_time`` timeline:

* ``world/drones/<name>``: pose (Transform3D: translation + quaternion) with a static body
  drawn under it (``.../frame``: arms and rotor discs; the leader red, followers blue) and
  its safety circle (``.../safety``, radius D̄/2 so two circles touch at the safety distance);
* ``world/trails/<name>``: the position as a point per sample (the blueprint shows the
  last 10 s as a trail);
* ``world/reference``: the leader's reference path (static); ``world/slots``: formation slots,
  all five per sample (the data); ``world/slot_markers/<follower>``: the same slot as a moving
  transform with a green dot under it, which is what the 3D view shows (a transform is drawn at
  the time cursor only, so the slot is a dot where the follower should be, not a 10-s smear
  that would hide the trails);
* ``plots/error/<name>``: position errors (x, y, z); ``plots/U/<name>``: U1..U4;
  ``plots/rotors/<name>``: F1..F4; ``plots/distance/leader/<follower>`` and
  ``plots/distance/followers/<fi>_<fj>`` (paper Fig. 14); ``plots/wind/speed`` and
  ``plots/wind/force`` (x, y); ``plots/anti_collision`` events as text;
* each extra force stage's force by the stage's name (x, y, z in N): ``plots/aero/<stage>/<name>``,
  e.g. ``plots/aero/downwash/<name>`` and ``plots/aero/ground_effect/<name>`` under the realistic
  preset (docs/aero.md); where the physics has the downwash, each drone's jet drawn under it
  (``world/drones/<name>/jet``: a frustum along the body's −z axis whose size follows the
  thrust, 1 m deep and as wide as the jet's half-width at hover thrust);
* under a sensing model (``result.log.views``; none under ``perfect``), what each drone believed:
  ``world/views/<observer>/ghosts``, ``world/views/<observer>/leader_link`` and
  ``views/<observer>/age/<other>`` (recording_views.py; the blueprint shows one observer's).

The file is written to ``<path>.partial`` and renamed when complete, so an existing
recording is never left half-written.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..metrics import follower_distances, leader_distances
from ..physics.params import DEFAULT_PARAMS, QuadParams

LEADER_COLOR = [220, 40, 40]
FOLLOWER_COLOR = [40, 110, 220]


def blueprint(names: list[str], aero: bool = False, views_period_s: float | None = None) -> rrb.Blueprint:
    """3D view beside the plots, so the file opens ready to read: the swarm with 10-s trails,
    the current slots (``world/slot_markers``), the reference path and the safety circles; the
    position errors and the distances (paper Fig. 14) on the right, U1..U4, rotor thrusts, wind
    and anti-collision events in tabs below them (``aero``: a tab of aerodynamic forces).
    ``views_period_s``: the run logged what each drone believed, every period of that length (s):
    one observer's ghosts in the 3D view, the others' hidden, and a tab of that observer's ages."""
    from .recording_views import age_overrides, view_overrides

    views = views_period_s is not None
    trail = rrb.VisibleTimeRange(
        "sim_time",
        start=rrb.TimeRangeBoundary.cursor_relative(seconds=-10.0),
        end=rrb.TimeRangeBoundary.cursor_relative(),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin="/world",
                name="swarm",
                contents=["+ /world/**", "- /world/slots"],
                time_ranges=[trail],
                overrides=view_overrides(names, views_period_s) if views_period_s is not None else None,
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/plots/error", name="position error (m)"),
                rrb.TimeSeriesView(origin="/plots/distance", name="distances (m, Fig. 14)"),
                rrb.Tabs(
                    rrb.TimeSeriesView(origin="/plots/U", name="U1..U4"),
                    rrb.TimeSeriesView(origin="/plots/rotors", name="rotor thrusts (N)"),
                    rrb.TimeSeriesView(origin="/plots/wind", name="wind"),
                    rrb.TextLogView(origin="/plots/anti_collision", name="anti-collision"),
                    *([rrb.TimeSeriesView(origin="/plots/aero", name="force stages (N)")] if aero else []),
                    *(
                        [
                            rrb.TimeSeriesView(
                                origin="/views", name="age of each view (s)", overrides=age_overrides(names)
                            )
                        ]
                        if views
                        else []
                    ),
                ),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _drone_shape(vehicle: QuadParams, color: list[int]) -> tuple[rr.LineStrips3D, rr.Ellipsoids3D]:
    """The drawn drone: arms of length L, rotor discs of the vehicle's rotor radius, a heading line;
    heights, thicknesses and the heading line are the paper drone's scaled by ``size_scale``."""
    L, r, k = vehicle.L, vehicle.rotor_radius, vehicle.size_scale
    (x1, y1), (x2, y2), (x3, y3), (x4, y4) = (vehicle.rotor_dirs * L).tolist()  # its layout ("+", "x")
    strips: list[list[list[float]]] = [
        [[x4, y4, 0], [x2, y2, 0]],
        [[x1, y1, 0], [x3, y3, 0]],
        [[0, 0, 0], [0.6 * L, 0, 0]],
    ]
    arms = rr.LineStrips3D(
        strips,
        colors=[color, color, [255, 140, 0]],
        radii=[0.012 * k, 0.012 * k, 0.015 * k],
    )
    h = 0.02 * k  # rotor plane above the centre
    rotors = rr.Ellipsoids3D(
        centers=[[x1, y1, h], [x2, y2, h], [x3, y3, h], [x4, y4, h]],
        half_sizes=[[r, r, 0.006 * k]] * 4,
        colors=[color] * 4,
        fill_mode=rr.components.FillMode.Solid,
    )
    return arms, rotors


def _circle(radius: float, m: int = 48) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, m + 1)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros_like(a)])


def _scalars(path: str, times, values: np.ndarray, names: list[str]) -> None:
    """A (k, m) block of scalars as one entity with m named series."""
    rr.log(path, rr.SeriesLines(names=names), static=True)
    rr.send_columns(path, indexes=[times], columns=rr.Scalars.columns(scalars=values))


def write_recording(result, path: str | Path, *, spawn: bool = False, safety_distance: float = 0.8) -> Path:
    """Write the run's recording to ``path`` (atomically) and return the path; ``spawn`` then opens
    it in the desktop viewer where a display exists (else a one-line note, see ``viewer.spawn_note``).
    The drones are drawn as the run's vehicle (``result.scenario.params``: arm, rotor radius, jet)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".partial")
    log = result.log
    names = log.names
    rec = rr.RecordingStream("swarm-mj", recording_id=f"{result.scenario.name}-{os.getpid()}")
    try:
        with rec:
            rr.save(
                tmp, default_blueprint=blueprint(names, aero=_has_aero(result), views_period_s=_views_period(result))
            )
            _log_run(result, names, _vehicle_of(result), safety_distance)
            rec.flush()
            rr.disconnect()
    except BaseException:
        # a failed or interrupted write leaves the previous recording as it was and no .partial
        rec.disconnect()
        tmp.unlink(missing_ok=True)
        raise
    from .atomic import replace_into

    replace_into(tmp, path)  # never replaces a FIFO or device; a symlink is written through
    if spawn:  # the file first: a viewer that cannot start (no display) never costs the recording
        import sys

        from .viewer import spawn_note

        print(spawn_note(path), file=sys.stderr)
    return path


def _vehicle_of(result) -> QuadParams:
    """The run's vehicle: its scenario's parameters (the paper's drone for a result without one)."""
    return getattr(getattr(result, "scenario", None), "params", DEFAULT_PARAMS)


def _log_run(result, names: list[str], vehicle: QuadParams, safety_distance: float) -> None:
    log = result.log
    t = log.t
    if len(t) == 0:
        return
    times = rr.TimeColumn("sim_time", duration=t)
    rr.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    ref = log.pos_d[:, 0]
    rr.log("/world/reference", rr.LineStrips3D([log.slot[:, 0]], colors=[[250, 180, 0]], radii=0.01), static=True)
    circle = _circle(safety_distance / 2)
    for i, name in enumerate(names):
        color = LEADER_COLOR if i == 0 else FOLLOWER_COLOR
        arms, rotors = _drone_shape(vehicle, color)
        base = f"/world/drones/{name}"
        rr.log(f"{base}/frame", arms, static=True)
        rr.log(f"{base}/rotors", rotors, static=True)
        rr.log(f"{base}/safety", rr.LineStrips3D([circle], colors=[[120, 120, 120]], radii=0.004), static=True)
        q = log.quat[:, i]
        rr.send_columns(
            base,
            indexes=[times],
            columns=rr.Transform3D.columns(
                translation=log.pos[:, i], quaternion=np.column_stack([q[:, 1], q[:, 2], q[:, 3], q[:, 0]])
            ),
        )
        rr.log(f"/world/trails/{name}", rr.Points3D.from_fields(colors=[color], radii=[0.015]), static=True)
        rr.send_columns(f"/world/trails/{name}", indexes=[times], columns=rr.Points3D.columns(positions=log.pos[:, i]))
        err = (log.slot[:, i] if i > 0 else ref) - log.pos[:, i]
        _scalars(f"/plots/error/{name}", times, err, ["x", "y", "z"])
        u = log.U[:, i]
        _scalars(f"/plots/U/{name}", times, u, ["U1", "U2", "U3", "U4"])
        _scalars(f"/plots/rotors/{name}", times, log.rotor[:, i], ["F1", "F2", "F3", "F4"])
    if len(names) > 1:
        slots = log.slot[:, 1:]
        n_f = slots.shape[1]
        rr.log("/world/slots", rr.Points3D.from_fields(colors=[[60, 200, 90]], radii=[0.03]), static=True)
        rr.send_columns(
            "/world/slots",
            indexes=[times],
            columns=rr.Points3D.columns(positions=slots.reshape(-1, 3)).partition([n_f] * len(t)),
        )
        for j in range(n_f):
            marker = f"/world/slot_markers/{names[j + 1]}"
            rr.log(f"{marker}/dot", rr.Points3D([[0.0, 0.0, 0.0]], colors=[[60, 200, 90]], radii=[0.06]), static=True)
            rr.send_columns(marker, indexes=[times], columns=rr.Transform3D.columns(translation=slots[:, j]))
        ld = leader_distances(log.pos)
        for j in range(n_f):
            _scalars(f"/plots/distance/leader/{names[j + 1]}", times, ld[:, j : j + 1], [f"L-{names[j + 1]}"])
        _scalars("/plots/distance/leader/D", times, log.D[:, None], ["D"])
        fd, pairs = follower_distances(log.pos)
        for c, (a, b) in enumerate(pairs):
            _scalars(
                f"/plots/distance/followers/{names[a]}_{names[b]}", times, fd[:, c : c + 1], [f"{names[a]}-{names[b]}"]
            )
    _scalars("/plots/wind/speed", times, log.wind_speed[:, :2], ["Vx (m/s)", "Vy (m/s)"])
    _scalars("/plots/wind/force", times, log.wind_force[:, 0, :2], ["Fx (N)", "Fy (N)"])
    if _has_aero(result):
        _log_aero(result, names, times, vehicle)
    if getattr(log, "views", None) is not None:
        from .recording_views import log_views

        log_views(log.views, log.pos, t, names, radius=0.05 * vehicle.size_scale)
    for ev in result.events:
        rr.set_time("sim_time", duration=ev["t"])
        other = names[ev["other"]] if ev["other"] >= 0 else ""
        rr.log("/plots/anti_collision", rr.TextLog(f"{names[ev['drone']]} {ev['action']} {other}".strip()))
    for tc, a, b in result.contact_log:
        rr.set_time("sim_time", duration=tc)
        rr.log("/plots/anti_collision", rr.TextLog(f"CONTACT {names[a]} - {names[b]}", level=rr.TextLogLevel.ERROR))


def _views_period(result) -> float | None:
    """The period (s) at which the run logged what each drone believed; None where it logged none."""
    log = result.log
    if getattr(log, "views", None) is None:
        return None
    return float(result.scenario.control_period)


def _has_aero(result) -> bool:
    """True when the run had extra force stages (the log keeps each one's force by name)."""
    return bool(getattr(result.log, "forces", None))


def _jet_frustum(vehicle: QuadParams, depth: float = 1.0, m: int = 24) -> list[np.ndarray]:
    """The drawn jet in the body frame (hover thrust): rings at depth 0 and ``depth`` (m) of the jet's
    half-width (swarm_mj.physics.aero.downwash) for the vehicle's motor distance 2L, joined by four lines."""
    from ..physics.aero.downwash import half_width

    l = 2 * vehicle.L  # the vehicle's motor distance (m)
    r0, r1 = float(half_width(0.0, l)), float(half_width(depth, l))
    top, bot = _circle(r0, m), _circle(r1, m)
    bot[:, 2] = -depth
    lines = [
        np.array([[r0 * np.cos(a), r0 * np.sin(a), 0.0], [r1 * np.cos(a), r1 * np.sin(a), -depth]])
        for a in np.arange(4) * np.pi / 2 + np.pi / 4
    ]
    return [top, bot, *lines]


def _log_aero(result, names: list[str], times, vehicle: QuadParams) -> None:
    log = result.log
    m_g = vehicle.hover_thrust
    jet = _jet_frustum(vehicle)
    for i, name in enumerate(names):
        for stage, force in log.forces.items():
            _scalars(f"/plots/aero/{stage}/{name}", times, force[:, i], ["Fx", "Fy", "Fz"])
        if result.summary.get("aero", {}).get("downwash"):
            base = f"/world/drones/{name}/jet"
            rr.log(base, rr.LineStrips3D(jet, colors=[[120, 190, 255, 110]], radii=0.004), static=True)
            scale = np.nan_to_num(log.rotor[:, i].sum(axis=1) / m_g, nan=0.0).clip(0.0, 3.0)
            rr.send_columns(
                base, indexes=[times], columns=rr.Transform3D.columns(scale=np.repeat(scale[:, None], 3, axis=1))
            )
