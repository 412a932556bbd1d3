"""``swarm-mj export crazyflie`` end to end (issue 50 "Done when"), the CLI in a subprocess as a user runs it.

* ``export crazyflie crazyflie_circle -o DIR --to 20`` writes a CSV per drone, path.csv, manifest.json and
  upload.py; each CSV has at most 31 pieces; the pieces, read from the CSVs and evaluated by this file's own
  Horner loop, lie within the tolerance of path.csv; the manifest's keep-out radii hold between every pair
  on them, densely; cflib packs them into the bytes they decode back from; upload.py answers --help with and
  without cflib;
* ``run DIR --aero realistic`` flies them back with 0 contacts and 0 s in the keep-out;
* what cannot fly is refused in one line naming the check, exit status 2, nothing written: the take-off
  (full thrust), a circle too fast for the vehicle, a flight too long for the memory.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.resources import SCENARIOS_DIR

CLI = [sys.executable, "-m", "swarm_mj.cli"]
pytestmark = pytest.mark.slow


def swarm(*args, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*CLI, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
    )


def refused(p: subprocess.CompletedProcess, check: str) -> str:
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ln.startswith("swarm-mj: error: ")]
    assert len(lines) == 1, p.stderr
    assert "export refused, nothing written" in lines[0] and f"{check}: " in lines[0], lines[0]
    return lines[0]


def read_pieces(path: Path) -> np.ndarray:
    rows = list(csv.reader(path.open()))
    return np.array(rows[1:], dtype=np.float64)  # (N, 33)


def horner_eval(rows: np.ndarray, t: np.ndarray) -> np.ndarray:
    """x, y, z, yaw (k, 4) of pieces rows (N, 33) at times t: the piece whose end is at or after t."""
    ends = np.cumsum(rows[:, 0])
    out = np.zeros((len(t), 4))
    for k, tk in enumerate(t):
        i = min(int(np.searchsorted(ends, tk, side="left")), len(rows) - 1)
        tau = tk - (ends[i] - rows[i, 0])
        for c in range(4):
            acc = 0.0
            for a in rows[i, 1 + 8 * c : 9 + 8 * c][::-1]:
                acc = acc * tau + a
            out[k, c] = acc
    return out


def read_path(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t, per = [], {}
    for row in csv.DictReader(path.open()):
        per.setdefault(row["drone"], []).append([float(row[c]) for c in ("t", "x", "y", "z", "yaw")])
    arr = {k: np.array(v) for k, v in per.items()}
    t = next(iter(arr.values()))[:, 0]
    return t, arr


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    cwd = tmp_path_factory.mktemp("export")
    p = swarm("export", "crazyflie", "crazyflie_circle", "-o", "DIR", "--to", 20, "--quiet", cwd=cwd)
    assert p.returncode == 0, p.stderr
    return cwd / "DIR"


def test_the_set_holds(exported):
    man = json.loads((exported / "manifest.json").read_text())
    names = [d["name"] for d in man["drones"]]
    assert names == ["leader"] + [f"follower{k}" for k in range(1, 6)]
    assert {p.name for p in exported.iterdir()} >= {f"{n}.csv" for n in names} | {"path.csv", "upload.py"}
    assert all(c["passed"] for c in man["checks"].values()), man["checks"]
    t, path = read_path(exported / "path.csv")
    assert t[-1] == pytest.approx(man["duration_s"]) and man["time_span_s"][1] == pytest.approx(20.0)
    dense = np.linspace(0, t[-1], 4 * len(t))
    on = {}
    for name in names:
        rows = read_pieces(exported / f"{name}.csv")
        assert 1 <= len(rows) <= 31 and rows.shape[1] == 33
        ev = horner_eval(rows, t)
        assert np.linalg.norm(ev[:, :3] - path[name][:, 1:4], axis=1).max() <= 0.01
        assert np.abs(ev[:, 3] - path[name][:, 4]).max() <= np.deg2rad(1.0)
        assert ev[0, :3] == pytest.approx(man["drones"][names.index(name)]["start"], abs=1e-6)
        on[name] = horner_eval(rows, dense)[:, :3]
    radii = np.array(man["keepout_radii_m"])
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            up = (on[a][:, 2] > man["airborne_m"]) & (on[b][:, 2] > man["airborne_m"])
            rho = np.linalg.norm((on[a] - on[b]) / radii, axis=1)
            assert up.any() and rho[up].min() >= 1.0, (a, b, rho[up].min())


class Handler:
    """cflib's memory handler, captured: the bytes TrajectoryMemory.write_data would send by radio."""

    def __init__(self) -> None:
        self.writes: list[tuple[int, bytes]] = []

    def write(self, mem, addr, data, flush_queue=False) -> None:
        self.writes.append((addr, bytes(data)))


def test_cflib_packs_the_exported_pieces(exported):
    pytest.importorskip("cflib")
    import struct

    from cflib.crazyflie.mem import MemoryElement, TrajectoryMemory

    sys.path.insert(0, str(exported))
    try:
        import upload  # the set's own upload.py
    finally:
        sys.path.remove(str(exported))
    t, path = read_path(exported / "path.csv")
    man, sets = upload.load_set(exported)
    for d, rows in zip(man["drones"], sets):
        handler = Handler()
        mem = TrajectoryMemory(id=1, type=MemoryElement.TYPE_TRAJ, size=4096, mem_handler=handler)
        mem.trajectory = upload.poly4d_list(rows)
        mem.write_data(lambda *a: None)
        ((addr, data),) = handler.writes
        assert addr == 0
        assert len(data) == 132 * len(rows) <= 4096
        back = np.array([struct.unpack("<33f", data[132 * i : 132 * (i + 1)]) for i in range(len(rows))])
        back = np.column_stack([back[:, 32], back[:, :32]])  # as a CSV row: the duration first
        ev = horner_eval(back, t)
        assert np.linalg.norm(ev[:, :3] - path[d["name"]][:, 1:4], axis=1).max() <= 0.01


def test_upload_py_runs_without_a_radio(exported):
    p = subprocess.run([sys.executable, str(exported / "upload.py"), "--help"], capture_output=True, text=True)
    assert p.returncode == 0 and "URI" in p.stdout, p.stderr
    block = (  # cflib made unimportable
        "import runpy, sys; sys.modules['cflib'] = None; sys.argv = sys.argv[1:]; "
        "runpy.run_path(sys.argv[0], run_name='__main__')"
    )
    uris = [f"radio://0/80/2M/E7E7E7E70{k}" for k in range(6)]
    p = subprocess.run([sys.executable, "-c", block, str(exported / "upload.py"), "--dry-run", *uris],
                       capture_output=True, text=True)  # fmt: skip
    assert p.returncode == 0 and "dry run" in p.stdout, p.stderr
    p = subprocess.run(
        [sys.executable, "-c", block, str(exported / "upload.py"), *uris], capture_output=True, text=True
    )
    assert p.returncode == 2 and "needs cflib" in p.stderr


def test_the_set_flown_back_is_clean(exported, tmp_path):
    p = swarm("run", exported, "--aero", "realistic", "--no-record", "--quiet", "--summary", "s.json", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    s = json.loads((tmp_path / "s.json").read_text())
    assert s["contacts"] == 0 and s["keepout_time_s"] == 0.0 and s["crashes"] == 0 and s["flight"]["ok"]
    assert s["anti_collision_rule"] == "off" and s["physics"] == "realistic"
    tr = s["export"]
    assert tr["within_1cm_from_s"] is not None and tr["within_1cm_from_s"] < s["sim_time_s"]


def test_the_take_off_at_full_thrust_is_refused(tmp_path):
    p = swarm("export", "crazyflie", "crazyflie_circle", "-o", "DIR", "--from", 0, "--to", 20, "--quiet", cwd=tmp_path)
    refused(p, "thrust")
    assert not any(tmp_path.iterdir())  # nothing written, no temporary folder left


def _crazyflie_circle(tmp_path: Path, **changes) -> Path:
    data = tomllib.loads((SCENARIOS_DIR / "crazyflie_circle.toml").read_text())
    data["controller"]["gains"] = str(SCENARIOS_DIR / data["controller"]["gains"])
    for key, value in changes.items():
        table, _, field = key.partition("__")
        if field:
            data.setdefault(table, {}).update({field: value})
        else:
            data[table] = value
    from swarm_mj.scenario import scenario_toml

    path = tmp_path / "sc.toml"
    path.write_text(scenario_toml(data))
    return path


def test_a_circle_too_fast_for_the_vehicle_is_refused(tmp_path):
    sc = _crazyflie_circle(tmp_path, leader__params={"radius": 1.0, "omega": 3.5, "altitude": 1.0})
    p = swarm("export", "crazyflie", sc, "-o", "DIR", "--from", 5, "--to", 15, "--quiet", cwd=tmp_path)
    line = refused(p, "thrust")
    assert "tilt: " in line
    assert not (tmp_path / "DIR").exists()


def test_a_flight_too_long_for_the_memory_is_refused(tmp_path):
    sc = _crazyflie_circle(tmp_path, wind={"enabled": True, "area": 0.008})  # gusts the pieces must follow
    p = swarm("export", "crazyflie", sc, "-o", "DIR", "--from", 5, "--to", 200, "--quiet", cwd=tmp_path)
    assert "more than 31 pieces" in refused(p, "pieces")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["sc.toml"]


def test_a_busy_folder_is_refused_before_flying(tmp_path):
    (tmp_path / "DIR").mkdir()
    (tmp_path / "DIR" / "mine.txt").write_text("keep")
    p = swarm("export", "crazyflie", "crazyflie_circle", "-o", "DIR", cwd=tmp_path, timeout=120)
    assert p.returncode == 2 and "neither empty nor an exported set" in p.stderr
    assert (tmp_path / "DIR" / "mine.txt").read_text() == "keep"
