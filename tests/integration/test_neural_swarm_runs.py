"""``swarm-mj validate downwash`` over the Neural-Swarm logs (docs/validation.md): the command writes its
tables, and a vehicle file sets the lower drone's plates. Skipped, saying so, where the logs are absent
(tests/helpers.py). The decoder, units, passes, formulas and the command's bad input are checked in
tests/unit/test_neural_swarm.py."""

from __future__ import annotations

import json

from helpers import DATA, SMALL, needs_data

from swarm_mj.cli import main as cli_main


@needs_data
def test_the_command_writes_the_tables(tmp_path, capsys):
    out = tmp_path / "v.json"
    assert cli_main(["validate", "downwash", "--data", str(DATA / SMALL), "--json", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    (row,) = doc["rows"]
    assert row["split"] == "held_out" and row["pairing"] == "crazyflie21 over crazyflie21"
    for key in ("n_passes", "rmse_g", "rmse_no_model_g", "mean_peak_measured_g", "mean_peak_error_g", "corr", "bins"):
        assert key in row
    assert row["n_passes"] == len(row["peaks"]) == sum(b["n_passes"] for b in row["bins"])
    assert doc["stacks"] and doc["stacks"][0]["pairing"] == "crazyflie21 + crazyflie21 over crazyflie21"
    assert not list(tmp_path.glob(".*partial"))
    assert "one drone above" in capsys.readouterr().out


@needs_data
def test_a_vehicle_file_sets_the_lower_drones_plates(tmp_path, capsys):
    """--vehicle maps a drone to a vehicle file; its hub_area / layout keys are used (here the Crazyflie's
    file without its hub plate), and a bad one is one line, exit 2."""
    from swarm_mj.vehicles import load_vehicle

    cf = load_vehicle("crazyflie21")
    good = tmp_path / "cf_nohub.toml"
    good.write_text(
        f"mass = 0.032\narm_length = {cf.arm_length}\nrotor_radius = {cf.rotor_radius}\nhub_area = 0.0\n"
        f'layout = "x"\nmotor_tau = {cf.motor_tau}\ndownwash_gain = {cf.downwash_gain}\n'
    )
    base = ["validate", "downwash", "--data", str(DATA / SMALL), "--quiet"]
    out = tmp_path / "a.json"
    assert cli_main([*base, "--json", str(out)]) == 0
    assert (
        cli_main(
            [*base, "--json", str(tmp_path / "b.json"), *sum((["--vehicle", f"cf5{i}={good}"] for i in range(3)), [])]
        )
        == 0
    )
    a, b = (json.loads((tmp_path / n).read_text())["rows"][0] for n in ("a.json", "b.json"))
    assert b["mean_peak_error_g"] > a["mean_peak_error_g"]  # no hub plate: a weaker push predicted
    assert json.loads((tmp_path / "b.json").read_text())["drones"]["cf50"]["vehicle"] == "cf_nohub"
    bad = tmp_path / "bad.toml"
    bad.write_text('mass = 0.032\narm_length = 0.046\nrotor_radius = 0.0235\nlayout = "h"\nmotor_tau = 0.06\n')
    capsys.readouterr()
    assert cli_main([*base, "--vehicle", f"cf50={bad}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'layout'" in err[0]
