"""The formation's smallest spacing and the barrier's refusal of a formation its keep-out cannot
reach (docs/barrier.md, "keep-out"): checked against the pairwise distances of the slots themselves."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.experiments.stress import StressCase, stress
from swarm_mj.formation.barrier import BarrierParams
from swarm_mj.formation.slots import check_formation_fits, min_slot_spacing, polygon_offsets
from swarm_mj.physics.params import DEFAULT_PARAMS


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 12, 24])
@pytest.mark.parametrize("D", [0.5, 1.0, 3.0])
def test_min_slot_spacing_is_the_smallest_pairwise_distance(n: int, D: float) -> None:
    pts = np.vstack([np.zeros(3), polygon_offsets(n, D)])  # the leader at the centre, then the slots
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    d[np.diag_indices_from(d)] = np.inf
    assert min_slot_spacing(n, D) == pytest.approx(d.min(), rel=1e-12)


def test_a_formation_inside_the_keepout_is_refused_naming_the_diameter_that_fits() -> None:
    width = float(BarrierParams().radii(DEFAULT_PARAMS)[0])  # 0.72 m: the paper's drone plus margins
    with pytest.raises(UserError, match="at least") as e:
        check_formation_fits(12, 1.0, width, "the barrier's keep-out")
    need = float(str(e.value).rsplit("at least ", 1)[1].split(" m")[0])
    check_formation_fits(12, need, width, "the barrier's keep-out")  # the D it names (rounded up) fits
    with pytest.raises(UserError):
        check_formation_fits(12, need - 0.01, width, "the barrier's keep-out")
    check_formation_fits(5, 1.0, width, "the barrier's keep-out")  # the paper's pentagon fits


def test_stress_refuses_twelve_followers_at_one_metre_with_barrier_before_flying() -> None:
    case = StressCase("barrier", 0, 12, 3.0, 0.6, 1.0)
    with pytest.raises(UserError, match="--diameter: 12 followers at D = 1 m"):
        stress(["barrier"], 1, case)
    with pytest.raises(UserError, match="--diameter must be positive"):
        stress(["layers"], 1, StressCase("layers", 0, 5, 3.0, 0.6, 1.0, diameter=-1.0))
