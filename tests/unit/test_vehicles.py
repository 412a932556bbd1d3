"""Vehicle files (docs/vehicles.md): the bundled ones load, bad files give one clear error."""

from __future__ import annotations

import pytest

from swarm_mj.errors import UserError
from swarm_mj.params import DEFAULT_PARAMS
from swarm_mj.vehicles import bundled, load_vehicle


def test_bundled_vehicles_load() -> None:
    assert {"paper", "crazyflie21"} <= set(bundled())
    for name in bundled():
        v = load_vehicle(name)
        assert v.mass > 0 and v.arm_length > 0 and v.rotor_radius > 0


def test_paper_vehicle_is_table1() -> None:
    v = load_vehicle("paper")
    assert v.mass == DEFAULT_PARAMS.m and v.arm_length == DEFAULT_PARAMS.L
    assert v.rotor_span == pytest.approx(0.34)


def test_vehicle_file_by_path(tmp_path) -> None:  # noqa: ANN001
    p = tmp_path / "mine.toml"
    p.write_text("mass = 1.2\narm_length = 0.2\nrotor_radius = 0.1\nkf = 3.0\n")
    v = load_vehicle(p)
    assert (v.name, v.mass, v.extra) == ("mine", 1.2, {"kf": 3.0})


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("arm_length = 0.2\nrotor_radius = 0.1\n", "'mass'"),
        ("mass = -1\narm_length = 0.2\nrotor_radius = 0.1\n", "'mass'"),
        ("mass = 1\narm_length = 'x'\nrotor_radius = 0.1\n", "'arm_length'"),
        ("mass = [", "cannot read"),
    ],
)
def test_bad_vehicle_file(tmp_path, text: str, needle: str) -> None:  # noqa: ANN001
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(UserError, match=needle):
        load_vehicle(p)


def test_unknown_vehicle() -> None:
    with pytest.raises(UserError, match="unknown vehicle"):
        load_vehicle("no_such_vehicle")
