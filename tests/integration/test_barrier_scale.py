"""The barrier filter at scale (issue 29, "It scales"; docs/barrier.md, "scale"): the bundled
25-drone circle (``scenarios/swarm25_barrier.toml``, 24 followers on D = 3 m) flies with no drone in
another's keep-out, no contact and no crash, under both physics. The keep-out time is recomputed from
the log with the metric's own function, so the summary's figure is checked, not trusted."""

from __future__ import annotations

import pytest

from swarm_mj.experiments.runner import run
from swarm_mj.formation.barrier import keepout_radii
from swarm_mj.metrics import keepout_time_s
from swarm_mj.scenario import load_scenario

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("aero", ["paper", "realistic"])
def test_25_drone_circle_holds_the_keepout(aero: str) -> None:
    sc = load_scenario("swarm25_barrier")
    assert sc.n_drones == 25
    res = run(sc, aero=aero, progress=False)
    s = res.summary
    assert s.get("stopped") is None
    assert s["anti_collision_rule"] == "barrier"
    assert keepout_time_s(res.log.t, res.log.pos, keepout_radii(sc.params)) == 0.0
    assert s["keepout_time_s"] == 0.0 and s["keepout_min_distance"] >= 1.0
    assert s["contacts"] == 0 and s["crashes"] == 0
    assert s["formation"]["settling_s"][0] < sc.duration  # it forms up within the run
