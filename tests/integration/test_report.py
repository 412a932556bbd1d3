"""Sweeps (determinism, statistics, parameters, errors) and the report's quick mode."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from swarm_mj.cli import main as cli_main
from swarm_mj.commands.sweep import parse_param
from swarm_mj.errors import UserError
from swarm_mj.experiments.sweep import (
    METRICS,
    apply_param,
    compute_stats,
    metric_stats,
    run_metrics,
    seeded,
    sweep,
)
from swarm_mj.physics.wind import ALWAYS_ON
from swarm_mj.scenario import load_scenario


def _windy(duration: float = 1.5):
    """wind_lemniscate with the wind on from t = 0, so that the seed matters within a short run."""
    sc = load_scenario("wind_lemniscate")
    return sc.with_overrides(wind=replace(sc.wind, schedule=ALWAYS_ON), duration=duration, steady_after=0.5)


# --------------------------------------------------------------------------- statistics


def test_metric_stats_known_values():
    v = [0.3, 0.1, 0.5, 0.2]
    s = metric_stats(v, [0, 1, 2, 3], "max")
    assert s["mean"] == pytest.approx(np.mean(v))
    assert s["std"] == pytest.approx(np.std(v, ddof=1))
    assert s["worst"] == 0.5 and s["worst_seed"] == 2 and s["best"] == 0.1
    assert s["n"] == 4 and s["n_nonfinite"] == 0
    s = metric_stats(v, [7, 8, 9, 10], "min")
    assert s["worst"] == 0.1 and s["worst_seed"] == 8 and s["best"] == 0.5
    # one value: std 0; infinities counted and worst; NaN ignored
    assert metric_stats([2.0], [0])["std"] == 0.0
    s = metric_stats([1.0, float("inf"), 3.0, float("nan")], [0, 1, 2, 3], "max")
    assert s["n"] == 3 and s["n_nonfinite"] == 1 and s["worst"] == float("inf") and s["worst_seed"] == 1
    assert s["mean"] == pytest.approx(2.0) and s["std"] == pytest.approx(np.std([1.0, 3.0], ddof=1))


def test_compute_stats_groups_by_value():
    runs = [
        {
            "value_index": vi,
            "seed": s,
            "metrics": {"rmse_x": 0.1 * (vi + 1) + 0.01 * s, "min_separation_m": 1 - 0.1 * s},
        }
        for vi in range(2)
        for s in range(3)
    ]
    st = compute_stats(runs, 2)
    assert st[0]["rmse_x"]["mean"] == pytest.approx(np.mean([0.10, 0.11, 0.12]))
    assert st[1]["rmse_x"]["worst"] == pytest.approx(0.22) and st[1]["rmse_x"]["worst_seed"] == 2
    assert st[1]["min_separation_m"]["worst"] == pytest.approx(0.8)  # min for separations
    assert "contacts" not in st[0]


# --------------------------------------------------------------------------- sweeps


def test_sweep_deterministic_across_workers_and_stats_match_runs():
    sc = _windy()
    a = sweep(sc, 2, "wind.sigma", [0.4, 1.2], workers=1)
    b = sweep(sc, 2, "wind.sigma", [0.4, 1.2], workers=2)
    assert [r["metrics"] for r in a.runs] == [r["metrics"] for r in b.runs]
    assert a.stats == b.stats
    # the seed and the value matter
    m = [r["metrics"]["rmse_steady_pitch_deg"] for r in a.runs]
    assert len(set(m)) == 4
    # statistics recomputed independently from the runs
    for vi, st in enumerate(a.stats):
        runs = [r for r in a.runs if r["value_index"] == vi]
        for key, worst, *_ in [(k, w) for k, _, w, swarm in METRICS if not swarm]:
            vals = np.array([r["metrics"][key] for r in runs])
            assert st[key]["mean"] == pytest.approx(vals.mean(), rel=1e-12, abs=1e-15)
            assert st[key]["std"] == pytest.approx(vals.std(ddof=1), rel=1e-9, abs=1e-15)
            assert st[key]["worst"] == (vals.max() if worst == "max" else vals.min())


def test_sweep_swarm_metrics_and_random_start_seed():
    sc = load_scenario("anti_collision")
    res = sweep(sc, [0], "formation.diameter", [1.0, 1.5], workers=1, duration=0.5)
    st = res.stats[0]
    for k in ("contacts", "min_separation_m", "formation_settling_s", "max_distance_error_m"):
        assert k in st
    from swarm_mj.report import random_crossing

    rc = random_crossing(1.0)
    assert not np.allclose(seeded(rc, 1).initial_positions(), seeded(rc, 2).initial_positions())


def test_parse_and_apply_param():
    assert parse_param("wind.sigma=0.4,0.8,1.2") == ("wind.sigma", [0.4, 0.8, 1.2])
    assert parse_param("wind.sigma=[0.8,0.5],[1.0,0.6]") == ("wind.sigma", [[0.8, 0.5], [1.0, 0.6]])
    assert parse_param("formation.anti_collision=layers,paper") == ("formation.anti_collision", ["layers", "paper"])
    assert parse_param("controller.wind_feedforward=true,false")[1] == [True, False]
    sc = load_scenario("wind_circle").with_overrides(gains=np.full(12, 5.0), gains_source="override")
    s2 = apply_param(sc, "wind.sigma", 0.3)
    assert s2.wind.sigma == (0.3, 0.3) and np.all(s2.gains == 5.0)  # earlier overrides survive
    s3 = apply_param(load_scenario("circle"), "formation.diameter", 1.5)
    assert s3.diameter == 1.5
    for bad in ("sigma", "wind.sigma=", "=1,2", "wind..sigma=1", "wind.sigma=1,,2", "wind.sigma=1,1"):
        with pytest.raises(UserError):
            parse_param(bad)
    with pytest.raises(UserError, match="no wind"):
        apply_param(load_scenario("circle_single"), "wind.sigma", 0.4)
    with pytest.raises(UserError, match="wind.sigma"):
        apply_param(load_scenario("wind_circle"), "wind.sigma", -1.0)


def test_run_metrics_single_drone_has_no_swarm_keys():
    from swarm_mj.experiments.runner import run

    m = run_metrics(run("step", duration=0.5).summary)
    assert "contacts" not in m and np.isnan(m["rmse_steady_x"])


# --------------------------------------------------------------------------- CLI errors


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["sweep", "no_such_scenario", "--seeds", "1"], "unknown scenario"),
        (["sweep", "wind_circle", "--seeds", "0"], "--seeds"),
        (["sweep", "wind_circle", "--param", "wind.sigma"], "KEY=V1"),
        (["sweep", "wind_circle", "--param", "wind.sigma=0.4,abc"], "wind.sigma"),
        (["sweep", "wind_circle", "--param", "wind.nope=1"], "nope"),
        (["sweep", "wind_circle", "--workers", "0"], "--workers"),
        (["report", "--workers", "0"], "--workers"),
    ],
)
def test_bad_input_one_line_exit_2(argv, needle, capsys):
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err


def test_sweep_cli_prints_worst_beside_mean_and_json(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert (
        cli_main(
            [
                "sweep",
                "wind_lemniscate",
                "--seeds",
                "2",
                "--duration",
                "0.5",
                "--workers",
                "1",
                "--json",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "mean" in text and "worst" in text and "leader RMSE x (m)" in text
    data = json.loads(out.read_text())
    assert data["seeds"] == [0, 1] and len(data["runs"]) == 2 and "rmse_x" in data["results"][0]["stats"]


# --------------------------------------------------------------------------- report


def test_report_quick_writes_readme_json_and_pngs(tmp_path, monkeypatch, capsys):
    from swarm_mj import report

    tiny = report.Plan(
        name="quick",
        table5_s=1.0,
        swarm_s=1.0,
        variable_d_s=6.5,
        anti_s=1.0,
        wind_seeds=2,
        wind_s=1.0,
        swarm_wind_seeds=1,
        swarm_wind_s=0.5,
        sigma_values=(0.4, 1.2),
        sigma_seeds=1,
        crossing_seeds=1,
        crossing_s=0.5,
        fpa_seeds=(1,),
        fpa_population=4,
        fpa_iterations=1,
        snapshot=False,
    )
    monkeypatch.setattr(report.Plan, "quick", classmethod(lambda cls: tiny))
    out = tmp_path / "rep"
    assert cli_main(["report", "--quick", "-o", str(out), "--workers", "2", "--quiet"]) == 0
    readme = (out / "README.md").read_text()
    for needle in (
        "Table 5",
        "Step response",
        "Variable D",
        "Anti-collision",
        "Interpretations",
        "circumradius",
        "RMSE twice",
        "mean ± std",
    ):
        assert needle in readme
    data = json.loads((out / "results.json").read_text())
    assert data["step"]["table4"]["axes"]["x"]["overshoot_pct"] >= 0
    assert len(data["table5"]["rows"]) >= 6 and data["sweeps"]["wind_lemniscate"]["seeds"] == [0, 1]
    assert data["gains"]["table4_ise"] > 0
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert {
        "fig07_step.png",
        "fig09_lemniscate.png",
        "fig14_variable_d.png",
        "fig15_wind.png",
        "swarm_paths_3d.png",
        "fig16_anticollision.png",
        "wind_robustness.png",
    } <= set(pngs)
    assert {f["file"] for f in data["figures"]} == set(pngs)
    import matplotlib.image as mpimg

    for name in pngs:
        img = mpimg.imread(out / name)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300
        assert (out / name).stat().st_size > 10_000
        assert float(np.std(img[..., :3])) > 0.01  # not blank
        assert f"({name})" in readme


# --------------------------------------------------------------------------- Ray (optional extra)


def test_ray_missing_is_one_line(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    assert cli_main(["sweep", "wind_lemniscate", "--seeds", "1", "--duration", "0.2", "--ray", "auto"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "swarm-mj[ray]" in err


class _Ref:
    def __init__(self, value):
        self.value = value


class _FakeRay:
    """Just enough of Ray's API, run in-process, completing in reverse order."""

    def __init__(self):
        self.inited = False

    def is_initialized(self):
        return self.inited

    def init(self, **kw):
        self.inited = True

    def shutdown(self):
        self.inited = False

    def remote(self, **kw):
        def wrap(fn):
            class R:
                @staticmethod
                def remote(x):
                    return _Ref(fn(x))

            return R

        return wrap

    def wait(self, pending, num_returns=1):
        return [pending[-1]], pending[:-1]

    def get(self, ref):
        return ref.value


def test_ray_backend_gives_the_same_stats(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "ray", _FakeRay())
    sc = _windy(0.6)
    a = sweep(sc, 2, workers=1)
    b = sweep(sc, 2, ray_address="local")
    assert b.backend == "ray" and a.stats == b.stats
    assert [r["seed"] for r in b.runs] == [0, 1]
