"""``swarm-mj export crazyflie`` piece by piece (docs/export.md): the fit, the commander's format, the
checks against independent calculations, cflib's packing, the flight back's reference and upload.py.

Every polynomial here is evaluated by this file's own Horner loop and differentiated by
``numpy.polynomial.polynomial``, not by swarm_mj.export.poly; the limits come from the vehicle's
parameters at run time."""

from __future__ import annotations

import csv
import io
import json
import struct
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import numpy.polynomial.polynomial as P
import pytest

from swarm_mj.errors import UserError
from swarm_mj.export import checks as ck
from swarm_mj.export import crazyflie as cfx
from swarm_mj.export import upload
from swarm_mj.export.flyback import PiecesReference, load_export
from swarm_mj.export.poly import Pieces, fit_adaptive, fit_pieces
from swarm_mj.vehicles import load_vehicle

#: uav_trajectories' header as genTrajectory.cpp writes it (whoenig/uav_trajectories, src/genTrajectory.cpp).
UAV_HEADER = (
    "Duration,x^0,x^1,x^2,x^3,x^4,x^5,x^6,x^7,y^0,y^1,y^2,y^3,y^4,y^5,y^6,y^7,"
    "z^0,z^1,z^2,z^3,z^4,z^5,z^6,z^7,yaw^0,yaw^1,yaw^2,yaw^3,yaw^4,yaw^5,yaw^6,yaw^7"
)


def horner(c, tau):
    """Σ c_j τ^j, ascending coefficients (this file's own evaluation)."""
    out = np.zeros_like(np.asarray(tau, dtype=float))
    for a in reversed(list(c)):
        out = out * tau + a
    return out


def evaluate(durations, coeffs, t, col):
    """Column ``col`` of pieces at times t: the piece whose end is at or after t (the firmware's walk)."""
    ends = np.cumsum(np.asarray(durations, dtype=np.float64))
    out = np.empty(len(t))
    for k, tk in enumerate(t):
        i = min(int(np.searchsorted(ends, tk, side="left")), len(ends) - 1)
        start = ends[i] - durations[i]
        out[k] = horner(np.asarray(coeffs[i][col], dtype=np.float64), tk - start)
    return out


def pieces_const(points: list[list[float]], duration: float = 2.0) -> list[Pieces]:
    """One constant piece per drone at each point (x, y, z)."""
    out = []
    for p in points:
        c = np.zeros((1, 4, 8))
        c[0, :3, 0] = p
        out.append(Pieces(durations=np.array([duration]), coeffs=c))
    return out


def test_a_degree_7_polynomial_is_fitted_exactly():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(4, 8)) * 0.3 ** np.arange(8)  # four columns, degree 7
    t = np.arange(0, 3.0 + 1e-9, 0.01)
    y = np.stack([P.polyval(t, q[c]) for c in range(4)], axis=1)
    v = np.stack([P.polyval(t, P.polyder(q[c])) for c in range(4)], axis=1)
    p = fit_pieces(t, y, np.array([0.0, 1.1, 2.0, 3.0]), v[0], v[-1])
    for c in range(4):
        assert np.abs(evaluate(p.durations, p.coeffs, t, c) - y[:, c]).max() < 1e-9


def test_pieces_join_up_to_the_third_derivative_and_meet_the_ends():
    t = np.arange(0, 4.0 + 1e-9, 0.01)
    y = np.column_stack([np.sin(3 * t) + 0.2 * t**2, np.cos(2 * t), np.tanh(4 * (t - 2)), 0.1 * t])
    v = np.column_stack([3 * np.cos(3 * t) + 0.4 * t, -2 * np.sin(2 * t), 4 / np.cosh(4 * (t - 2)) ** 2, 0.1 + 0 * t])
    p = fit_pieces(t, y, np.array([0.0, 0.7, 1.9, 2.6, 4.0]), v[0], v[-1])
    h = p.durations
    for i in range(len(h) - 1):
        for c in range(4):
            for r in range(4):
                left = P.polyval(h[i], P.polyder(p.coeffs[i, c], r))
                right = P.polyval(0.0, P.polyder(p.coeffs[i + 1, c], r))
                assert left == pytest.approx(right, rel=1e-6, abs=1e-6), (i, c, r)
    for c in range(4):
        assert P.polyval(0.0, p.coeffs[0, c]) == pytest.approx(y[0, c], abs=1e-9)
        assert P.polyval(0.0, P.polyder(p.coeffs[0, c])) == pytest.approx(v[0, c], abs=1e-8)
        assert P.polyval(h[-1], p.coeffs[-1, c]) == pytest.approx(y[-1, c], abs=1e-9)
        assert P.polyval(h[-1], P.polyder(p.coeffs[-1, c])) == pytest.approx(v[-1, c], abs=1e-8)


def test_the_adaptive_fit_meets_the_tolerance_in_float32_arithmetic():
    t = np.arange(0, 10.0 + 1e-9, 0.01)
    bump = 0.3 * np.tanh(5 * (t - 4))
    y = np.column_stack([np.sin(0.7 * t) + bump, 0.5 * np.cos(1.3 * t), 1.0 + 0.1 * t + bump, 0.2 * np.sin(0.5 * t)])
    v0 = np.array([0.7 + 1.5 / np.cosh(20) ** 2, 0.0, 0.1 + 1.5 / np.cosh(20) ** 2, 0.1])
    v1 = np.array([0.7 * np.cos(7) + 1.5 / np.cosh(30) ** 2, -0.65 * np.sin(13), 0.1, 0.1 * np.cos(5)])
    tol = np.array([0.01, np.deg2rad(1.0)])
    p = fit_adaptive(t, y, v0, v1, tol, [slice(0, 3), slice(3, 4)], 31)
    assert p is not None and 1 < p.n_pieces <= 31
    d32, c32 = np.asarray(p.durations, np.float32), np.asarray(p.coeffs, np.float32)
    ends = np.cumsum(d32.astype(np.float64))
    err = np.zeros(len(t))
    for k, tk in enumerate(t):  # float32 arithmetic, as the commander's polyval
        i = min(int(np.searchsorted(ends, tk, side="left")), len(ends) - 1)
        tau = np.float32(tk - (ends[i] - d32[i]))
        ev = [np.float32(0)] * 4
        for c in range(4):
            for a in reversed(c32[i, c]):
                ev[c] = np.float32(ev[c] * tau + a)
        err[k] = max(np.linalg.norm(np.array(ev[:3], float) - y[k, :3]) / tol[0], abs(float(ev[3]) - y[k, 3]) / tol[1])
    assert err.max() <= 1.0
    assert fit_adaptive(t, y, v0, v1, tol, [slice(0, 3), slice(3, 4)], 2) is None  # the bump needs more than two


def test_the_commanders_sizes():
    # crazyflie-firmware: TRAJECTORY_MEMORY_SIZE 4096, "4k allows us to store 31 poly4d pieces"; struct poly4d
    # is float p[4][8] and a float duration
    assert ck.MEMORY_BYTES == 4096
    assert ck.BYTES_PER_PIECE == struct.calcsize("<33f") == 132
    assert ck.MAX_PIECES == 31


def _some_pieces(n: int = 3) -> Pieces:
    rng = np.random.default_rng(1)
    return Pieces(durations=rng.uniform(0.3, 2.0, n), coeffs=rng.normal(size=(n, 4, 8)))


def test_pack_is_the_poly4d_layout():
    p = _some_pieces()
    data = cfx.pack(p)
    assert len(data) == 132 * p.n_pieces
    for i in range(p.n_pieces):
        vals = struct.unpack("<33f", data[132 * i : 132 * (i + 1)])
        assert np.array_equal(np.array(vals[:32], np.float32), np.asarray(p.coeffs[i], np.float32).reshape(-1))
        assert np.float32(vals[32]) == np.float32(p.durations[i])


def test_the_csv_is_uav_trajectories_and_reads_back_exactly(tmp_path):
    p = _some_pieces()
    text = cfx.csv_text(p)
    rows = list(csv.reader(io.StringIO(text)))
    assert ",".join(rows[0]) == UAV_HEADER
    assert all(len(r) == 33 for r in rows[1:]) and len(rows) == 1 + p.n_pieces
    vals = np.array(rows[1:], dtype=np.float64).astype(np.float32)
    assert np.array_equal(vals[:, 0], np.asarray(p.durations, np.float32))
    assert np.array_equal(vals[:, 1:].reshape(-1, 4, 8), np.asarray(p.coeffs, np.float32))
    (tmp_path / "d.csv").write_text(text)
    back = cfx.read_csv(tmp_path / "d.csv")
    assert np.array_equal(back.coeffs, np.asarray(p.coeffs, np.float32))
    (tmp_path / "bad.csv").write_text("t,x\n1,2\n")
    with pytest.raises(UserError, match="bad.csv"):
        cfx.read_csv(tmp_path / "bad.csv")


class _Handler:
    """cflib's memory handler, captured: what TrajectoryMemory.write_data would send over the radio."""

    def __init__(self):
        self.writes = []

    def write(self, mem, addr, data, flush_queue=False):
        self.writes.append((addr, bytes(data)))


def test_cflib_packs_the_same_bytes_and_they_decode_to_the_pieces():
    pytest.importorskip("cflib")
    from cflib.crazyflie.mem import MemoryElement, TrajectoryMemory

    p = _some_pieces(4)
    rows = [[float(v) for v in r] for r in list(csv.reader(io.StringIO(cfx.csv_text(p))))[1:]]
    handler = _Handler()
    mem = TrajectoryMemory(id=1, type=MemoryElement.TYPE_TRAJ, size=4096, mem_handler=handler)
    mem.trajectory = upload.poly4d_list(rows)
    n = mem.write_data(lambda *a: None)
    (addr, data), = handler.writes  # fmt: skip
    assert addr == 0 and n == len(data) == 132 * 4
    assert data == cfx.pack(p)
    t = np.linspace(0, float(np.sum(np.asarray(p.durations, np.float32))), 50)
    dec = [struct.unpack("<33f", data[132 * i : 132 * (i + 1)]) for i in range(4)]
    durs = np.array([d[32] for d in dec])
    coeffs = np.array([np.array(d[:32]).reshape(4, 8) for d in dec])
    for c in range(4):
        want = evaluate(np.asarray(p.durations, np.float32), np.asarray(p.coeffs, np.float32), t, c)
        assert np.allclose(evaluate(durs, coeffs, t, c), want, rtol=0, atol=1e-12)


def _vehicle():
    return load_vehicle("crazyflie21").params()


def _vertical(a: float, duration: float) -> list[Pieces]:
    """z = 1 + a t²/2 for ``duration`` s: the thrust needed grows with the speed (drag) to the end."""
    c = np.zeros((1, 4, 8))
    c[0, 2, 0], c[0, 2, 2] = 1.0, a / 2
    return [Pieces(durations=np.array([duration]), coeffs=c)]


@pytest.mark.parametrize("share, passes", [(0.79, True), (0.81, False)])
def test_the_thrust_check_is_the_vehicles_force(share, passes):
    v = _vehicle()
    T = 1.0
    # at the end: m (a + g) + K_z a T = share · 4 f_max (Newton with the vehicle's linear drag)
    a = (share * 4 * v.f_max - v.m * v.g) / (v.m + v.Kz * T)
    out = ck.thrust_checks(_vertical(a, T), ["d"], ck.dense_times(T, 0.01), v, ck.Limits())
    thrust = out[0]
    assert thrust.name == "thrust" and thrust.passed is passes
    assert thrust.value == pytest.approx(share, rel=1e-6)


@pytest.mark.parametrize("deg, passes", [(44.0, True), (46.0, False)])
def test_the_tilt_check(deg, passes):
    v = _vehicle()
    T = 0.05
    # x = a t²/2: the rotors' force (m a + K_x a t, m g) leans atan(.../m g) from the vertical, most at the end
    a = v.m * v.g * np.tan(np.deg2rad(deg)) / (v.m + v.Kx * T)
    c = np.zeros((1, 4, 8))
    c[0, 0, 2], c[0, 2, 0] = a / 2, 1.0
    p = [Pieces(durations=np.array([T]), coeffs=c)]
    tilt = ck.thrust_checks(p, ["d"], ck.dense_times(T, 0.01), v, ck.Limits())[1]
    assert tilt.passed is passes
    assert np.rad2deg(tilt.value) == pytest.approx(deg, rel=1e-6)


@pytest.mark.parametrize("axis, share, passes", [(0, 0.99, False), (0, 1.01, True), (2, 0.99, False), (2, 1.01, True)])
def test_the_keepout_check(axis, share, passes):
    v = _vehicle()
    width = 2 * (v.L + v.rotor_radius)  # rotor tip to rotor tip of two level drones (docs/barrier.md)
    radius = width * (1 if axis == 0 else 3)  # three rotor spans tall
    b = [0.0, 0.0, 1.0]
    b[axis] += share * radius
    keep, take = ck.keepout_checks(pieces_const([[0.0, 0.0, 1.0], b]), ["a", "b"], np.linspace(0, 2, 50), v)
    assert keep.passed is passes
    assert keep.value == pytest.approx(share, rel=1e-9)
    assert take.passed is (axis == 0 and share >= 1)  # straight up from the floor: only the distance across counts


def test_starts_a_keepout_width_apart_across_take_off_clear_of_it():
    # docs/export.md, "takeoff": two drones rising straight up at once, their heights anything, stay out of
    # the ellipsoid when their starts are at least its width apart across
    from swarm_mj.formation.barrier import keepout_radii
    from swarm_mj.metrics import keepout_distance

    radii = keepout_radii(_vehicle())
    rng = np.random.default_rng(2)
    across = rng.normal(size=(1000, 2))
    across *= (radii[0] * rng.uniform(1.0, 1.5, 1000) / np.linalg.norm(across, axis=1))[:, None]
    up = rng.uniform(-3.0, 3.0, 1000)  # any difference of heights
    assert keepout_distance(np.column_stack([across, up]), radii).min() >= 1.0 - 1e-12


def test_the_keepout_counts_airborne_pairs_only():
    v = _vehicle()
    keep, take = ck.keepout_checks(pieces_const([[0.0, 0.0, 0.05], [0.05, 0.0, 0.05]]), ["a", "b"], np.zeros(3), v)
    assert keep.passed and take.passed  # on the floor, as the run summary counts it


def test_the_tolerance_check_names_the_drone():
    t = np.arange(0, 2.0, 0.01)
    pos = np.zeros((len(t), 2, 3)) + [0.0, 0.0, 1.0]
    pos[:, 1, 0] = 1.0
    pieces = pieces_const([[0.0, 0.0, 1.0], [1.015, 0.0, 1.0]])
    out = {c.name: c for c in ck.fit_checks(pieces, ["a", "b"], t, pos, np.zeros((len(t), 2)), ck.Limits())}
    assert not out["tolerance"].passed and out["tolerance"].drone == "b"
    assert out["tolerance"].value == pytest.approx(0.015, abs=1e-6)
    assert out["pieces"].passed and out["memory"].passed
    assert "tolerance: b's pieces" in (ck.failures(list(out.values())) or "")


def test_the_flight_back_reference_walks_the_pieces_as_the_firmware():
    a, b = _some_pieces(3), _some_pieces(1)
    ref = PiecesReference([a, b])
    ends = np.cumsum(np.asarray(a.durations, np.float64))
    for t in [0.0, ends[0], ends[0] + 1e-6, 0.5 * (ends[1] + ends[2]), ends[2]]:
        pos, vel, acc, yaw = ref(t)
        i = min(int(np.searchsorted(ends, t, side="left")), 2)  # t <= the piece's end: that piece
        tau = t - (ends[i] - a.durations[i])
        c = np.asarray(a.coeffs[i], np.float64)
        for col in range(3):
            assert pos[0, col] == pytest.approx(horner(c[col], tau), abs=1e-9)
            assert vel[0, col] == pytest.approx(horner(P.polyder(c[col]), tau), abs=1e-9)
            assert acc[0, col] == pytest.approx(horner(P.polyder(c[col], 2), tau), abs=1e-9)
        assert yaw[0] == pytest.approx(horner(c[3], tau), abs=1e-9)
    pos, vel, acc, _ = ref(ends[-1] + 5.0)  # after the end: the last point, at rest
    last = np.asarray(a.coeffs[-1], np.float64)
    assert pos[0] == pytest.approx([horner(last[col], a.durations[-1]) for col in range(3)])
    assert not vel[0].any() and not acc[0].any()


def _a_set(folder: Path, names=("leader", "follower1")) -> None:
    folder.mkdir(exist_ok=True)
    drones = []
    for i, name in enumerate(names):
        (folder / f"{name}.csv").write_text(cfx.csv_text(pieces_const([[i * 0.5, 0.0, 1.0]])[0]))
        drones.append({"name": name, "csv": f"{name}.csv", "start": [i * 0.5, 0.0, 1.0], "start_yaw_rad": 0.0})
    (folder / "manifest.json").write_text(json.dumps({"format": cfx.FORMAT, "drones": drones, "duration_s": 2.0}))


def test_upload_py_needs_no_cflib_for_help_and_dry_run(tmp_path, monkeypatch, capsys):
    for mod in [m for m in sys.modules if m == "cflib" or m.startswith("cflib.")]:
        monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setitem(sys.modules, "cflib", None)  # import cflib raises ImportError
    with pytest.raises(SystemExit) as e:
        upload.parse_args(["--help"])
    assert e.value.code == 0
    _a_set(tmp_path / "set")
    assert upload.main(["--folder", str(tmp_path / "set"), "--dry-run", "radio://0/80/2M/1", "radio://0/80/2M/2"]) == 0
    assert "place it on the floor at x = 0.500" in capsys.readouterr().out
    assert upload.main(["--folder", str(tmp_path / "set"), "radio://0/80/2M/1"]) == 2  # one URI per drone
    assert upload.main(["--folder", str(tmp_path / "set"), "radio://0/80/2M/1", "radio://0/80/2M/2"]) == 2
    assert "needs cflib" in capsys.readouterr().err


def test_the_cflib_note(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "cflib" else real(n, *a))
    assert "upload.py needs cflib" in (cfx.cflib_note() or "")


def test_the_output_folder(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="not a folder"):
        cfx.check_output_folder(tmp_path / "file")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("x")
    with pytest.raises(UserError, match="neither empty nor an exported set"):
        cfx.check_output_folder(tmp_path / "busy")
    with pytest.raises(UserError, match="does not exist"):
        cfx.check_output_folder(tmp_path / "no" / "such")
    (tmp_path / "empty").mkdir()
    cfx.check_output_folder(tmp_path / "empty")
    _a_set(tmp_path / "earlier")
    cfx.check_output_folder(tmp_path / "earlier")  # an earlier set is replaced
    cfx.write_set(tmp_path / "earlier", {"manifest.json": "{}", "upload.py": ""})
    assert sorted(p.name for p in (tmp_path / "earlier").iterdir()) == ["manifest.json", "upload.py"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy", "earlier", "empty", "file"]  # nothing left aside


def test_a_folder_that_is_not_a_set(tmp_path):
    with pytest.raises(UserError, match="without manifest.json"):
        load_export(tmp_path)
    _a_set(tmp_path / "s")
    (tmp_path / "s" / "manifest.json").write_text(json.dumps({"format": "other", "drones": []}))
    with pytest.raises(UserError, match="not a manifest"):
        load_export(tmp_path / "s")


def test_the_plan_starts_when_the_swarm_has_formed():
    t = np.arange(0, 5.0, 0.01)
    k = len(t)
    ref = np.zeros((k, 2, 3)) + [0.0, 0.0, 1.0]
    pos = ref.copy()
    pos[:180, 1, 2] -= 0.5  # follower climbing until 1.8 s
    pos[180:230, 1, 2] -= 0.049  # inside the 5-cm band from 1.8 s
    log = SimpleNamespace(t=t, pos=pos, slot=ref, pos_d=ref)
    assert cfx.default_from(log, k - 1) == pytest.approx(1.8)
    pos[-1, 0, 0] = 0.2  # the leader leaves its reference at the end: never formed
    with pytest.raises(UserError, match="--from"):
        cfx.default_from(log, k - 1)
