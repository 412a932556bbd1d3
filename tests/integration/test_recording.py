"""The .rrd written by ``swarm-mj run`` (issue 4): read back with Rerun's own reader and compared
with the simulation; every entity of recording.py's docstring is there; writes are atomic."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
pytest.importorskip("datafusion")  # rerun-sdk[catalog]: reading a recording back needs it

from swarm_mj.cli import main as cli_main  # noqa: E402
from swarm_mj.experiments.runner import run  # noqa: E402

DURATION = 20.0
SEED = 0
RERUN = Path(sys.executable).with_name("rerun")


def read_rrd(path: Path):
    """All columns of a recording on the sim_time index, as a pandas DataFrame (docs/libraries.md)."""
    with rr.server.Server(datasets={"ds": [str(path)]}) as server:
        client = server.client()  # keep every object alive until the query has run
        dataset = client.get_dataset("ds")
        df = dataset.reader(index="sim_time").to_pandas()
    return df


def col(df, name: str) -> np.ndarray:
    """A component column as float64 (k, m, d): one batch of m instances per row."""
    return np.array([np.stack(list(v)).astype(np.float64) for v in df[name]])


def scalars(df, name: str) -> np.ndarray:
    return np.array([np.asarray(v, dtype=np.float64) for v in df[name]])


@pytest.fixture(scope="module")
def circle(tmp_path_factory):
    """``swarm-mj run circle --duration 20`` and, independently, runner.run with the same seed."""
    d = tmp_path_factory.mktemp("rec")
    out = d / "circle.rrd"
    rc = cli_main(
        [
            "run",
            "circle",
            "--duration",
            str(DURATION),
            "--seed",
            str(SEED),
            "-o",
            str(out),
            "--summary",
            str(d / "circle.json"),
            "--quiet",
        ]
    )
    assert rc == 0
    result = run("circle", duration=DURATION, seed=SEED, progress=False)
    assert result.error is None
    df = read_rrd(out)
    return out, df, result


def test_recording_is_written_and_verifies(circle):
    out, _, _ = circle
    assert out.exists() and out.stat().st_size > 0
    assert not out.with_name(out.name + ".partial").exists()
    if RERUN.exists():
        p = subprocess.run([str(RERUN), "rrd", "verify", str(out)], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr


def test_timeline_is_the_control_period(circle):
    _, df, result = circle
    t = df["sim_time"].to_numpy().astype("timedelta64[ns]").astype(np.int64) / 1e9
    np.testing.assert_allclose(t, result.log.t, atol=1e-9)
    assert len(t) == round(DURATION / 0.01) + 1


def test_logged_poses_equal_the_simulated_ones(circle):
    _, df, result = circle
    log = result.log
    for i, name in enumerate(log.names):
        tr = col(df, f"/world/drones/{name}:Transform3D:translation")[:, 0]
        np.testing.assert_allclose(tr, log.pos[:, i], rtol=2e-7, atol=1e-6, err_msg=name)
        q = col(df, f"/world/drones/{name}:Transform3D:quaternion")[:, 0]  # Rerun order x, y, z, w
        np.testing.assert_allclose(q, log.quat[:, i][:, [1, 2, 3, 0]], atol=1e-6, err_msg=name)
        trail = col(df, f"/world/trails/{name}:Points3D:positions")[:, 0]
        np.testing.assert_allclose(trail, log.pos[:, i], rtol=2e-7, atol=1e-6, err_msg=name)
    # the leader really flew the circle of docs/interpretations.md §3 (not just "whatever the log says")
    t = log.t
    late = t >= 10.0
    leader = col(df, "/world/drones/leader:Transform3D:translation")[:, 0]
    ref = np.column_stack([2.5 * np.sin(0.08 * t), 2.5 * np.cos(0.08 * t), np.full_like(t, 2.0)])
    assert np.abs(leader[late] - ref[late]).max() < 0.01


def test_plots_hold_the_logged_signals(circle):
    _, df, result = circle
    log = result.log
    n = len(log.names)
    for i, name in enumerate(log.names):
        err = scalars(df, f"/plots/error/{name}:Scalars:scalars")
        ref = log.pos_d[:, 0] if i == 0 else log.slot[:, i]
        np.testing.assert_allclose(err, ref - log.pos[:, i], atol=2e-6, err_msg=name)
        U = scalars(df, f"/plots/U/{name}:Scalars:scalars")
        np.testing.assert_allclose(U[:-1], log.U[:-1, i], rtol=2e-7, atol=1e-6, err_msg=name)
        F = scalars(df, f"/plots/rotors/{name}:Scalars:scalars")
        np.testing.assert_allclose(F[:-1], log.rotor[:-1, i], rtol=2e-7, atol=1e-6, err_msg=name)
        assert (F[:-1] >= -1e-6).all() and (F[:-1] <= 4.5 + 1e-6).all()
    # paper Fig. 14: horizontal leader–follower and follower–follower distances, and D
    for j in range(1, n):
        dist = scalars(df, f"/plots/distance/leader/{log.names[j]}:Scalars:scalars")[:, 0]
        np.testing.assert_allclose(
            dist, np.linalg.norm(log.pos[:, j, :2] - log.pos[:, 0, :2], axis=1), rtol=2e-7, atol=1e-6
        )
        for k in range(j + 1, n):
            dd = scalars(df, f"/plots/distance/followers/{log.names[j]}_{log.names[k]}:Scalars:scalars")[:, 0]
            np.testing.assert_allclose(
                dd, np.linalg.norm(log.pos[:, j, :2] - log.pos[:, k, :2], axis=1), rtol=2e-7, atol=1e-6
            )
    np.testing.assert_allclose(scalars(df, "/plots/distance/leader/D:Scalars:scalars")[:, 0], 1.0)
    ws = scalars(df, "/plots/wind/speed:Scalars:scalars")
    wf = scalars(df, "/plots/wind/force:Scalars:scalars")
    assert ws.shape == (len(log.t), 2) and wf.shape == (len(log.t), 2)
    np.testing.assert_allclose(wf[:-1], log.wind_force[:-1, 0, :2], atol=1e-6)


def test_slots_reference_and_safety_circles(circle):
    _, df, result = circle
    log = result.log
    slots = col(df, "/world/slots:Points3D:positions")
    assert slots.shape == (len(log.t), 5, 3)
    np.testing.assert_allclose(slots, log.slot[:, 1:], rtol=2e-7, atol=1e-6)
    # slots: a pentagon of circumradius D = 1 around the leader's position (docs/interpretations.md §4)
    r = np.linalg.norm(slots[:, :, :2] - log.pos[:, None, 0, :2], axis=-1)
    np.testing.assert_allclose(r, 1.0, atol=1e-5)
    strips = df["/world/reference:LineStrips3D:strips"].dropna().iloc[-1]
    path = np.stack(list(strips[0])).astype(np.float64)
    t = log.t
    np.testing.assert_allclose(
        path, np.column_stack([2.5 * np.sin(0.08 * t), 2.5 * np.cos(0.08 * t), np.full_like(t, 2.0)]), atol=1e-6
    )
    for name in log.names:
        circ = df[f"/world/drones/{name}/safety:LineStrips3D:strips"].dropna().iloc[-1]
        pts = np.stack(list(circ[0])).astype(np.float64)
        np.testing.assert_allclose(np.linalg.norm(pts[:, :2], axis=1), 0.4, atol=1e-6)  # D̄/2


def test_every_documented_entity_is_present(circle):
    """The entity list of swarm_mj/output/recording.py's docstring."""
    _, df, result = circle
    names = result.log.names
    entities = {c.split(":")[0] for c in df.columns if c.startswith("/")}
    expected = {
        "/world/reference",
        "/world/slots",
        "/plots/wind/speed",
        "/plots/wind/force",
        "/plots/distance/leader/D",
    }
    for name in names:
        expected |= {
            f"/world/drones/{name}",
            f"/world/drones/{name}/frame",
            f"/world/drones/{name}/safety",
            f"/world/trails/{name}",
            f"/plots/error/{name}",
            f"/plots/U/{name}",
            f"/plots/rotors/{name}",
        }
    for f in names[1:]:
        expected.add(f"/plots/distance/leader/{f}")
    for a in range(1, len(names)):
        for b in range(a + 1, len(names)):
            expected.add(f"/plots/distance/followers/{names[a]}_{names[b]}")
    if result.events or result.contact_log:
        expected.add("/plots/anti_collision")
    missing = expected - entities
    assert not missing, sorted(missing)
    # drones carry transforms (translation + rotation), not just points
    for name in names:
        assert f"/world/drones/{name}:Transform3D:translation" in df.columns
        assert f"/world/drones/{name}:Transform3D:quaternion" in df.columns


def test_anti_collision_events_are_logged_as_text(circle):
    _, df, result = circle
    if not (result.events or result.contact_log):
        pytest.skip("no anti-collision events in this run")
    names = result.log.names
    expected = {}
    for ev in result.events:
        other = names[ev["other"]] if ev["other"] >= 0 else ""
        expected.setdefault(round(ev["t"], 6), set()).add(f"{names[ev['drone']]} {ev['action']} {other}".strip())
    for tc, a, b in result.contact_log:
        expected.setdefault(round(tc, 6), set()).add(f"CONTACT {names[a]} - {names[b]}")
    rows = df[["sim_time", "/plots/anti_collision:TextLog:text"]].dropna()
    # the reader gives one row per instant (events at the same instant share it), so compare instants
    seen = {}
    for tt, v in zip(rows["sim_time"], rows["/plots/anti_collision:TextLog:text"]):
        seen[round(tt.total_seconds(), 6)] = set(v)
    assert set(seen) == set(expected)
    for tt, texts in seen.items():
        assert texts <= expected[tt], (tt, texts, expected[tt])


def test_summary_file_agrees_with_the_recording(circle):
    import json

    out, df, result = circle
    s = json.loads(out.with_name("circle.json").read_text())
    assert s["scenario"] == "circle" and s["sim_time_s"] == pytest.approx(DURATION)
    leader = col(df, "/world/drones/leader:Transform3D:translation")[:, 0]
    ex = np.sqrt(np.mean((result.log.pos_d[:, 0, 0] - leader[:, 0]) ** 2))
    assert s["drones"]["leader"]["rmse"]["x"] == pytest.approx(ex, rel=1e-4, abs=1e-6)


# --------------------------------------------------------------------------- atomic writes


def test_failed_write_keeps_the_existing_recording(tmp_path, monkeypatch, circle):
    """A write that fails half-way leaves the previous file untouched (written to .partial, then renamed)."""
    import swarm_mj.output.recording as recording

    src, _, _ = circle
    target = tmp_path / "keep.rrd"
    shutil.copy(src, target)
    before = target.read_bytes()
    res = run("step", duration=0.5, progress=False)

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(recording, "_log_run", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        recording.write_recording(res, target)
    assert target.read_bytes() == before
    assert not (tmp_path / "keep.rrd.partial").exists(), "a failed write must not leave a .partial behind"


def test_write_recording_replaces_an_existing_file(tmp_path):
    from swarm_mj.output.recording import write_recording

    target = tmp_path / "r.rrd"
    target.write_bytes(b"old")
    res = run("step", duration=0.5, progress=False)
    assert write_recording(res, target) == target
    assert target.read_bytes() != b"old"
    assert sorted(os.listdir(tmp_path)) == ["r.rrd"]
    df = read_rrd(target)
    np.testing.assert_allclose(
        col(df, "/world/drones/leader:Transform3D:translation")[:, 0], res.log.pos[:, 0], rtol=2e-7, atol=1e-6
    )
