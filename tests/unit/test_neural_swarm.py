"""The downwash validation against the Neural-Swarm logs (docs/validation.md): the decoder, the
dataset's units, the residual force, pass detection, gym-pybullet-drones' formula, the travelling
wake and the command's bad input. The command over the logs: tests/integration/test_neural_swarm_runs.py.

The tests that read the dataset look for it at ``../shared/neural-swarm`` from the repository root
(or at ``$NEURAL_SWARM_DATA``; tests/helpers.py) and are skipped, saying so, where it is absent.
"""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from helpers import DATA, SMALL, needs_data

from swarm_mj.cli import main as cli_main
from swarm_mj.physics.aero.downwash import BD, S0, hover_induced_velocity
from swarm_mj.physics.aero.wake import emitted_state, transport_time
from swarm_mj.validation.decode import decode, decode_bytes
from swarm_mj.validation.flight import find_flights, load_flight, quat_decompress
from swarm_mj.validation.passes import find_passes
from swarm_mj.validation.predict import gym_force, jet_force
from swarm_mj.validation.sysid import G, read_thrust_model, readme_assignments, residual_force_g


def small_flight():
    session = DATA / SMALL.split("/")[0]
    (found,) = [f for f in find_flights(DATA / SMALL)]
    return session, load_flight(*found)


# --------------------------------------------------------------------------- decoder and units


@needs_data
def test_decoder_reads_every_block_with_a_good_crc_and_the_configured_variables():
    session = DATA / SMALL.split("/")[0]
    log = decode(DATA / SMALL / "cf50_00")
    assert log.crc_errors == 0 and log.n_blocks > 100
    # config.txt lists the logged variables in order (after five setting lines); the decoder adds tick
    listed = [ln.strip() for ln in (session / "config.txt").read_text().splitlines()[5:] if ln.strip()]
    assert list(log.columns) == ["tick", *listed]
    # 18 s at 100 Hz (config.txt's frequency), within the records' count
    assert len(log) == pytest.approx(1800, rel=0.05)


@needs_data
def test_crc_catches_a_corrupted_block_and_drops_only_its_records():
    raw = (DATA / SMALL / "cf50_00").read_bytes()
    good = decode_bytes(raw)
    bad = bytearray(raw)
    bad[len(raw) // 2] ^= 0x40  # one bit in the middle of the file
    hurt = decode_bytes(bytes(bad))
    assert hurt.crc_errors == 1
    lost = len(good) - len(hurt)
    assert 1 <= lost <= 25  # one block (the config's buffer size is 25 records)
    assert set(hurt["tick"]).issubset(set(good["tick"]))


def test_crc_convention_is_the_residue_of_the_checked_span_and_its_crc():
    """A log built by hand: header 'tick(I),z(h),' + CRC, one block of two records + CRC."""

    def with_crc(b: bytes) -> bytes:
        # the stored CRC makes crc32(span + stored) == 0xFFFFFFFF: the complement of crc32(span), little-endian
        return b + struct.pack("<I", zlib.crc32(b) ^ 0xFFFFFFFF)

    header = with_crc(bytes([2]) + b"tick(I),z(h),")
    assert zlib.crc32(header) & 0xFFFFFFFF == 0xFFFFFFFF
    block = with_crc(bytes([2]) + struct.pack("<Ih", 10000, -5) + struct.pack("<Ih", 20000, 7))
    log = decode_bytes(header + block)
    assert log.crc_errors == 0
    assert list(log["tick"]) == [10000, 20000] and list(log["z"]) == [-5, 7]


@needs_data
def test_time_base_is_microseconds_monotonic_at_100_hz():
    log = decode(DATA / SMALL / "cf51_00")
    dt = np.diff(log["tick"].astype(np.int64))
    assert np.all(dt > 0)
    assert np.median(dt) == pytest.approx(10_000, rel=0.02)  # µs: 100 Hz
    assert log["tick"][-1] * 1e-6 == pytest.approx(18.0, abs=0.2)  # the flight's 18 s (learning/training.py: 17.98 s)


@needs_data
def test_units_against_the_setpoints_and_gravity():
    """Positions in mm (they follow the setpoint, also mm), accelerations in mm/s² with gravity
    (≈ +9810 in hover), quaternions unit and near level, voltage in mV of a 1S LiPo."""
    session, f = small_flight()
    for name in f.drones:
        raw = decode(DATA / SMALL / f"{name}_00")
        err = raw["stateEstimateZ.z"].astype(float) - raw["ctrltargetZ.z"]
        assert abs(np.median(err)) < 50  # mm: a few cm off the setpoint (×10 if the unit were cm)
        assert np.median(raw["stateEstimateZ.az"]) == pytest.approx(9810, rel=0.02)
        q = quat_decompress(raw["stateEstimateZ.quat"])
        assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
        tilt = np.degrees(np.arccos(np.clip(1 - 2 * (q[:, 0] ** 2 + q[:, 1] ** 2), -1, 1)))
        assert np.median(tilt) < 10
        assert 3000 < np.median(raw["pm.vbatMV"]) < 4300


def test_quaternion_decompression_against_a_hand_compressed_quaternion():
    q = np.array([0.1, -0.2, 0.05, 0.0])
    q[3] = math.sqrt(1 - np.sum(q[:3] ** 2))  # w largest
    comp = 3 << 30  # index of the largest
    for i in range(3):  # stored from index 0 at the most significant end to index 2 at the least
        mag = round(abs(q[i]) * math.sqrt(2) * 511)
        comp |= ((mag | ((1 if q[i] < 0 else 0) << 9)) & 0x3FF) << (10 * (2 - i))
    out = quat_decompress(np.array([comp], dtype=np.uint32))[0]
    assert np.allclose(out, q, atol=1.0 / 511 / math.sqrt(2))


# --------------------------------------------------------------------------- system identification


@needs_data
def test_thrust_model_by_hand_and_the_readme_assignments():
    session = DATA / SMALL.split("/")[0]
    assert readme_assignments(session)["cf52"] == "defaultcf.txt"
    m = read_thrust_model(session / "defaultcf.txt")
    p, v = 0.6, 3.7 / 4.2
    by_hand = 11.093358483549203 - 39.08104165843915 * p - 9.525647087583181 * v + 20.573302305476638 * p * p
    by_hand += 38.42885066644033 * v * p
    assert float(m.rotor_thrust_g(np.array(p), np.array(v))) == pytest.approx(by_hand, rel=1e-12)
    assert m.mass_g is None  # defaultcf.txt gives no mass; parrot_frame.txt does
    assert read_thrust_model(session / "parrot_frame.txt").mass_g == 67.0


@needs_data
def test_residual_is_near_zero_for_the_drone_with_nothing_above_it():
    """The top drone flies in free air: Fa_z ≈ 0 on average (a few % of its weight) with the dataset's
    32 g; a stock 27-g Crazyflie's mass would leave −5 g."""
    session, f = small_flight()
    top = max(f.drones.values(), key=lambda g: g.pos[:, 2].mean())
    model = read_thrust_model(session / "defaultcf.txt")
    fa = residual_force_g(top, model, 32.0, 0.16)
    assert abs(fa[:, 2].mean()) < 2.5
    assert abs(fa[:, :2].mean(axis=0)).max() < 2.5
    assert residual_force_g(top, model, 27.0, 0.16)[:, 2].mean() < -4.0


@needs_data
def test_the_lower_drone_is_pushed_down_during_a_pass():
    session, f = small_flight()
    pos = np.stack([g.pos for g in f.drones.values()])
    bottom = int(np.argmin(pos[:, :, 2].mean(axis=1)))
    passes = find_passes(pos, bottom, 0.1, 0.3, 0.1)
    assert passes
    fa = residual_force_g(list(f.drones.values())[bottom], read_thrust_model(session / "defaultcf.txt"), 32.0, 0.16)
    for p in passes:
        assert fa[p.start : p.stop, 2].min() < -8.0  # a quarter of its weight, at least
    quiet = np.ones(len(f.t), bool)
    for p in passes:
        quiet[p.start : p.stop] = False
    assert abs(fa[quiet, 2].mean()) < 2.5


# --------------------------------------------------------------------------- passes


def _line(k: int, v: float, dz: float, y: float = 0.0) -> np.ndarray:
    """(2, k, 3): drone 0 at rest at the origin, drone 1 at height dz flying along x at v m/s, 10-ms samples,
    from x = −1 m, offset y sideways."""
    t = 0.01 * np.arange(k)
    pos = np.zeros((2, k, 3))
    pos[1, :, 0] = -1.0 + v * t
    pos[1, :, 1] = y
    pos[1, :, 2] = dz
    return pos


def test_pass_by_hand():
    pos = _line(401, 0.5, 0.3)  # over the origin at t = 2 s (sample 200)
    (p,) = find_passes(pos, 0, r_pass=0.1, r_window=0.3025, dz_min=0.1)
    assert (p.lower, p.uppers, p.i_min) == (0, (1,), 200)
    # |x| < 0.3025 m: x = −1 + 0.005 i, so 139.5 < i < 260.5
    assert (p.start, p.stop) == (140, 261)
    assert p.dz == pytest.approx(0.3) and p.r_min == pytest.approx(0.0, abs=1e-12)
    assert find_passes(pos, 1, 0.1, 0.3, 0.1) == []  # nothing above the upper drone


def test_no_pass_when_aside_level_or_cut_by_the_log():
    assert find_passes(_line(401, 0.5, 0.3, y=0.15), 0, 0.1, 0.3, 0.1) == []  # never within 0.1 m
    assert find_passes(_line(401, 0.5, 0.05), 0, 0.1, 0.3, 0.1) == []  # level: 5 cm above
    assert find_passes(_line(300, 0.5, 0.3)[:, 150:], 0, 0.1, 0.3, 0.1) == []  # starts inside the window


def test_two_drones_over_one_make_a_stack():
    a = _line(401, 0.5, 0.3)
    pos = np.concatenate([a, a[1:] * [-1, 1, 2]])  # a third drone from the other side, 0.6 m up
    (p,) = find_passes(pos, 0, 0.1, 0.3, 0.1)
    assert p.stack and p.uppers == (1, 2)


# --------------------------------------------------------------------------- models


def test_gym_pybullet_drones_formula_by_hand():
    R, c = 0.0231348, (2267.18, 0.16, -0.11)
    src = np.array([[0.0, 0.0, 1.3], [0.0, 0.0, 1.0], [0.0, 0.0, 0.9]])
    dst = np.array([[0.05, 0.0, 1.0], [0.0, 0.0, 1.2], [0.0, 0.0, 0.9]])
    f = gym_force(src, dst, R, c)
    alpha = 2267.18 * (0.0231348 / (4 * 0.3)) ** 2  # 0.8427 N
    beta = 0.16 * 0.3 - 0.11  # −0.062 m
    assert f[0, 2] == pytest.approx(-alpha * math.exp(-0.5 * (0.05 / beta) ** 2), rel=1e-12)
    assert f[0, 2] == pytest.approx(-0.6087, abs=1e-4)  # 0.8427 N × exp(−0.3252)
    assert np.all(f[1:] == 0.0) and np.all(f[:, :2] == 0.0)  # nothing from below or level


@pytest.mark.parametrize("layout", ["+", "x"])
def test_jet_force_against_the_formula_by_hand(layout, tmp_path):
    """jet_force (the simulator's compiled jet_on_drone) against docs/aero.md's force written out here with
    numpy: the lower drone's four rotor discs at its layout's rotor centres (typed in) and its hub, each
    ½ ρ C_D A U(s, r)² along the jet, U from the module's pure jet_speed, × the upper vehicle's gain."""
    from swarm_mj.physics.aero.constants import AIR_DENSITY, DISC_DRAG_COEFFICIENT
    from swarm_mj.physics.aero.downwash import jet_speed
    from swarm_mj.vehicles import load_vehicle

    f = tmp_path / "v.toml"
    f.write_text(f'mass = 0.5\narm_length = 0.2\nrotor_radius = 0.07\nlayout = "{layout}"\nhub_area = 0.01\n'
                 "downwash_gain = 1.3\n")  # fmt: skip
    veh = load_vehicle(f)
    c = 1 / math.sqrt(2)
    dirs = [(0, -1), (1, 0), (0, 1), (-1, 0)] if layout == "+" else [(c, -c), (-c, -c), (-c, c), (c, c)]
    rng = np.random.default_rng(7)
    for _ in range(6):
        src = np.array([0.0, 0.0, 2.0])
        axis = np.array([*rng.uniform(-0.1, 0.1, 2), 1.0])
        dst = np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(0.8, 1.8)])
        q = np.array([*rng.uniform(-0.1, 0.1, 3), 1.0])  # x, y, z, w
        q /= np.linalg.norm(q)
        x, y, z, w = q
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        d = -axis / np.linalg.norm(axis)
        u_h = math.sqrt(4.8 / (2 * AIR_DENSITY * 4 * math.pi * 0.07**2))
        want = np.zeros(3)
        plates = [(R @ np.array([0.2 * a, 0.2 * b, 0.0]), math.pi * 0.07**2) for a, b in dirs] + [(np.zeros(3), 0.01)]
        for off, area in plates:
            rel = dst + off - src
            s = rel @ d
            r = np.linalg.norm(rel - s * d)
            u = float(jet_speed(s, r, u_h, 0.4, ramp=0.07))
            want += 1.3 * 0.5 * AIR_DENSITY * DISC_DRAG_COEFFICIENT * area * u * u * d
        got = jet_force(src[None], axis[None], np.array([4.8]), veh, dst[None], q[None], veh)
        assert got[0] == pytest.approx(want, rel=1e-9, abs=1e-12)


def test_transport_time_is_the_integral_of_the_centreline_speed():
    u_h, l = 4.3, 0.092
    for s in (0.05, 0.3, 0.6):
        x = np.linspace(0.0, s, 20001)
        inv = (x / l - S0) / (u_h * BD)  # 1 / U_c
        assert transport_time(s, u_h, l) == pytest.approx(
            float(np.sum((inv[1:] + inv[:-1]) / 2 * np.diff(x))), rel=1e-8
        )
    assert transport_time(-0.1, u_h, l) == 0.0 and transport_time(0.3, 0.0, l) == 0.0


def test_a_drone_at_constant_speed_leaves_its_wake_v_tau_behind():
    """Analytic case: the wake's axis at depth s passes v τ(s) behind where the drone is now."""
    v = np.array([0.8, -0.3, 0.0])
    times = 0.01 * np.arange(300)
    track = np.array([0.2, 0.1, 1.5]) + times[:, None] * v
    u_h = float(hover_induced_velocity(0.032 * G, 1.225, 0.0235))
    now = np.array([2.5])
    for s in (0.1, 0.3, 0.5):
        tau = transport_time(np.array([s]), u_h, 0.092)
        src = emitted_state(now, tau, times, track)[0]
        here = np.interp(2.5, times, track[:, 0]), np.interp(2.5, times, track[:, 1])
        offset = np.array(here) - src[:2]
        assert offset == pytest.approx(v[:2] * tau[0], rel=1e-9)
        assert np.linalg.norm(offset) == pytest.approx(np.linalg.norm(v) * (s * s / 0.184 - S0 * s) / (u_h * BD))


# --------------------------------------------------------------------------- the command


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--data", "/nonexistent/folder"], "no such folder"),
        (["--data", "{empty}"], "no Neural-Swarm logs"),
        (["--data", "{data}", "--vehicle", "cf50"], "expected ID=VALUE"),
        (["--data", "{data}", "--vehicle", "drone=crazyflie21"], "expected ID=VALUE"),
        (["--data", "{data}", "--vehicle", "cf50=no_such_vehicle"], "unknown vehicle"),
        (["--data", "{data}", "--mass", "cf50=-3"], "positive"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, words, tmp_path, capsys):
    data = DATA / SMALL if DATA.is_dir() else tmp_path
    argv = [a.format(empty=tmp_path, data=data) for a in argv]
    assert cli_main(["validate", "downwash", *argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("swarm-mj: error:") and words in err[0]


@needs_data
def test_unknown_drone_in_a_mapping_is_refused(capsys):
    assert (
        cli_main(["validate", "downwash", "--data", str(DATA / SMALL), "--vehicle", "cf99=crazyflie21", "--quiet"]) == 2
    )
    assert "no log of cf99" in capsys.readouterr().err


@needs_data
def test_the_stored_downwash_gain_is_the_fit_on_the_calibration_flights_alone():
    """crazyflie21.toml's downwash_gain is the least-squares gain over the calibration flights' single
    passes: refit here from those flights only (the held-out flights are not read), the factor on top
    of the stored gain is 1 to the gain's printed digits."""
    from swarm_mj.validation.analysis import Setup, analyse_flight, calibrate_gain
    from swarm_mj.validation.flight import load_flight
    from swarm_mj.validation.params import CALIBRATION
    from swarm_mj.vehicles import load_vehicle

    setup = Setup()
    found = []
    for session, experiment in CALIBRATION:
        for flight in find_flights(DATA / session / experiment):
            found += [q for q in analyse_flight(load_flight(*flight), setup) if not q.p.stack]
    assert {q.split for q in found} == {"calibration"} and len(found) >= 40
    gain = load_vehicle("crazyflie21").downwash_gain
    assert gain * calibrate_gain(found) == pytest.approx(gain, abs=5e-4)


def test_resampling_marks_a_gap_in_a_log_invalid():
    from swarm_mj.validation.flight import DroneLog

    t = np.concatenate([0.01 * np.arange(10), 0.2 + 0.01 * np.arange(10)])  # records 0.09 → 0.20 s: a 110-ms gap
    k = len(t)
    log = DroneLog(
        "cf1",
        Path("x"),
        t,
        np.zeros((k, 3)),
        np.zeros((k, 3)),
        np.zeros((k, 3)),
        np.tile([0.0, 0.0, 0.0, 1.0], (k, 1)),
        np.zeros((k, 4)),
        np.full(k, 3.7),
        0,
    )
    grid = 0.01 * np.arange(30)
    valid = log.resample(grid).valid
    assert valid is not None
    assert np.array_equal(np.flatnonzero(~valid), np.arange(10, 20))  # 0.10 … 0.19 s lie in the gap
