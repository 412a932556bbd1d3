"""Aerodynamics beyond the paper (swarm_mj.physics.aero, docs/aero.md) over whole runs: the floor gate
leaves a touchdown run bit-identical, the realistic preset takes off from rest, the paper preset is the
recorded reproduction to the last bit, the recording holds the aerodynamic forces, and a start below
the ground is refused by the command line (one line, exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.physics.aero import with_aero
from swarm_mj.physics.aero.ground import REST_HEIGHT
from swarm_mj.physics.params import DEFAULT_PARAMS as P
from swarm_mj.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]


def test_floor_gate_gives_the_same_run_bit_for_bit(monkeypatch, touchdown_scenario):
    """A take-off from rest, flight, and a touchdown (the floor tested, then not, then again): the
    same log as with the floor tested at every physics step."""
    import swarm_mj.physics.sim as sim_module
    from swarm_mj.experiments.runner import RunLog, run

    sc = touchdown_scenario
    step, floor_on = sim_module.Sim.step, []

    def spy(self, U, wind_force=None):  # noqa: ANN001, ANN202 - the floor's state over each period
        step(self, U, wind_force)
        floor_on.append(bool(self.model.geom_contype[self._gate[0]]))

    monkeypatch.setattr(sim_module.Sim, "step", spy)
    gated = run(sc, progress=False, fused=False)
    monkeypatch.setattr(sim_module.Sim, "step", step)
    switches = np.flatnonzero(np.diff(floor_on))
    assert len(switches) == 2 and floor_on.count(False) > 100  # on at rest, off aloft, on for the touchdown
    monkeypatch.setattr(sim_module, "floor_gate", lambda world: None)
    tested = run(sc, progress=False, fused=False)
    assert gated.summary["ground_contacts"] == 1 and gated.summary["crashes"] == 0
    assert gated.log.views is None and tested.log.views is None  # the oracle: no beliefs to log
    for f in RunLog.__dataclass_fields__:
        if f not in ("names", "forces", "views"):  # forces: views of stage_rows
            assert np.array_equal(getattr(gated.log, f), getattr(tested.log, f), equal_nan=True), f


def test_realistic_run_takes_off_from_rest():
    from swarm_mj.experiments.runner import run

    sc = with_aero(load_scenario("step"), "realistic")
    res = run(sc, progress=False, duration=3.0)
    assert res.error is None
    assert res.log.pos[0, 0, 2] == pytest.approx(REST_HEIGHT)
    assert res.log.pos[-1, 0, 2] == pytest.approx(1.0, abs=0.05)
    assert res.summary["crashes"] == 0 and res.summary["ground_contacts"] == 0
    assert res.summary["aero"]["model"] == "realistic"
    # produced rotor thrust starts at zero and lags the command
    assert res.log.rotor[0, 0].sum() < res.log.U[0, 0, 0]


@pytest.mark.parametrize(
    "doc,field",
    [
        ('duration = 2.0\n[leader]\ntrajectory = "step"\nparams = { target = [1.0, 1.0, -0.4] }\n', "leader.params"),
        (
            'duration = 2.0\n[leader]\ntrajectory = "hover"\n[followers]\n'
            "start = [[1.5, 0.0, 0.0], [3.0, 0.0, -1.0]]\n",
            "followers.start",
        ),
        ('duration = 2.0\n[leader]\ntrajectory = "hover"\nstart = [0.0, 0.0, -0.1]\n', "leader.start"),
    ],
)
def test_below_ground_is_refused_with_exit_2(tmp_path, doc, field):
    f = tmp_path / "bad.toml"
    f.write_text(doc)
    for aero in ("paper", "realistic"):
        p = subprocess.run(
            [sys.executable, "-m", "swarm_mj.cli", "run", str(f), "--no-record", "--quiet", "--aero", aero],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        assert p.returncode == 2, p.stderr
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("swarm-mj: error:") and field in lines[0]
        assert "below the ground" in lines[0]


def test_paper_preset_is_bit_identical_to_the_recorded_reproduction():
    """Under ``paper`` (the default of every bundled scenario) the step response is the one the report
    recorded (report/results.json, Table 4 gains), to the last bit."""
    from swarm_mj.experiments.runner import run

    rec = json.loads((ROOT / "report" / "results.json").read_text())["step"]["table4"]
    res = run(load_scenario("step"), progress=False)
    assert res.scenario.aero.is_paper
    steps = res.summary["drones"]["leader"]["step"]
    for ax in ("x", "y", "z", "psi"):
        assert steps[ax]["overshoot_pct"] == rec["axes"][ax]["overshoot_pct"]
        assert steps[ax]["settling_s"] == rec["axes"][ax]["settling_s"]
    assert res.summary["drones"]["leader"]["max_abs_pitch_deg"] == rec["max_abs_pitch_deg"]
    assert res.summary["crashes"] == 0 and res.summary["ground_contacts"] == 0
    assert np.all(res.log.downwash == 0) and np.all(res.log.ground_effect == 0)


def test_recording_holds_aero_forces_and_jets(tmp_path):
    """Rerun: each drone's downwash and ground-effect force as time series equal to the run's log, and
    its jet drawn under it with a scale that follows its thrust."""
    rr = pytest.importorskip("rerun")
    pytest.importorskip("datafusion")
    from swarm_mj.experiments.runner import run
    from swarm_mj.output.recording import write_recording

    res = run(with_aero(load_scenario("anti_collision"), "realistic"), progress=False, duration=3.0)
    assert res.error is None
    out = write_recording(res, tmp_path / "a.rrd")
    with rr.server.Server(datasets={"ds": [str(out)]}) as server:
        client = server.client()  # keep every object alive until the query has run
        dataset = client.get_dataset("ds")
        df = dataset.reader(index="sim_time").to_pandas()
    log = res.log
    assert np.abs(log.downwash).max() > 0.05 and np.abs(log.ground_effect).max() > 0.05
    # one row per logged sample: an event logged at a sample's time (the formation settling, say) adds a
    # row of that time without these columns
    df = df[df[f"/plots/aero/downwash/{log.names[0]}:Scalars:scalars"].notna()]
    assert len(df) == len(log.t)
    for i, name in enumerate(log.names):
        dw = np.array([np.asarray(v, float) for v in df[f"/plots/aero/downwash/{name}:Scalars:scalars"]])
        ge = np.array([np.asarray(v, float) for v in df[f"/plots/aero/ground_effect/{name}:Scalars:scalars"]])
        np.testing.assert_allclose(dw, log.downwash[:, i], atol=1e-6)
        np.testing.assert_allclose(ge, log.ground_effect[:, i], atol=1e-6)
        scale = np.array(
            [np.stack(list(v)).astype(float).ravel() for v in df[f"/world/drones/{name}/jet:Transform3D:scale"]]
        )
        np.testing.assert_allclose(
            scale[:, 0], np.clip(log.rotor[:, i].sum(axis=1) / (P.m * P.g), 0, 3), rtol=1e-6, atol=1e-6
        )
