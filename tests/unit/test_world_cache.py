"""build_world keeps the compiled model of its arguments and hands out copies (swarm_mj/physics/world.py,
docs/design.md "Start-up and the step's own cost"): a kept build is the same model, bit for bit, as
composing and compiling it again, and no world's model reaches another's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from swarm_mj.physics import world as world_mod
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.physics.world import WORLD_CACHE_SIZE, build_world, clear_world_cache
from swarm_mj.resources import QUADROTOR_XML

STARTS = np.array([[0.0, 0.0, 1.0], [1.0, 0.5, 1.0], [-1.0, 0.5, 1.2]])


def model_bytes(model: mujoco.MjModel) -> bytes:
    """The whole model as MuJoCo serialises it (every array and option)."""
    buf = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    return buf.tobytes()


def fresh(**kw) -> bytes:
    """The model composed and compiled from nothing (the cache emptied first)."""
    clear_world_cache()
    return model_bytes(build_world(**kw).model)


@pytest.fixture(autouse=True)
def _empty_cache():
    clear_world_cache()
    yield
    clear_world_cache()


def test_a_kept_build_is_the_same_model_bit_for_bit():
    kw = dict(n_drones=3, positions=STARTS, yaws=[0.3, 0.0, -0.2])
    first = build_world(**kw)
    again = build_world(**kw)
    assert again.model is not first.model  # each build its own copy
    assert model_bytes(again.model) == model_bytes(first.model) == fresh(**kw)
    assert again.xml == first.xml
    assert np.array_equal(again.body_ids, first.body_ids) and np.array_equal(again.geom_drone, first.geom_drone)


def test_other_starts_are_another_model_each_equal_to_a_fresh_build():
    a = dict(n_drones=3, positions=STARTS)
    b = dict(n_drones=3, positions=STARTS + [0.25, -0.5, 0.75])
    wa, wb, wa2 = build_world(**a), build_world(**b), build_world(**a)
    assert model_bytes(wa.model) != model_bytes(wb.model)
    assert np.array_equal(wb.model.qpos0.reshape(3, 7)[:, :3], b["positions"])  # b's starts, not a's
    assert model_bytes(wa2.model) == model_bytes(wa.model) == fresh(**a)
    assert model_bytes(build_world(**b).model) == model_bytes(wb.model) == fresh(**b)


def test_writing_a_world_model_does_not_reach_a_later_build():
    kw = dict(n_drones=2, positions=STARTS[:2], ground=True)
    expected = fresh(**kw)
    w = build_world(**kw)
    w.model.geom_contype[:] = 7  # what the solid floor's gate writes
    w.model.body_mass[:] = 123.0
    w.model.opt.timestep = 0.5
    w.body_ids[:] = -1
    later = build_world(**kw)
    assert model_bytes(later.model) == expected
    assert later.model.opt.timestep == 0.005 and (later.body_ids >= 0).all()


@pytest.mark.parametrize(
    "change",
    [
        dict(yaws=[0.0, 0.0, 1e-12]),
        dict(params=DEFAULT_PARAMS.__class__(**{**DEFAULT_PARAMS.__dict__, "m": DEFAULT_PARAMS.m * 1.01})),
        dict(timestep=0.004),
        dict(integrator="Euler"),
        dict(collisions=False),
        dict(floor=False),
        dict(torque_motors="site"),
        dict(ground=True),
        dict(motor_tau=0.02),
        dict(names=["a", "b", "c"]),
    ],
)
def test_every_argument_is_part_of_the_key(change):
    base = dict(n_drones=3, positions=STARTS)
    before = model_bytes(build_world(**base).model)
    changed = model_bytes(build_world(**base, **change).model)
    assert changed != before
    assert changed == fresh(**base, **change)


def test_negative_zero_start_is_its_own_key():
    # -0.0 == 0.0, but the two compile to different bits of body_pos: the key is the bytes
    neg = STARTS.copy()
    neg[0, 0] = -0.0
    build_world(n_drones=3, positions=STARTS)
    assert model_bytes(build_world(n_drones=3, positions=neg).model) == fresh(n_drones=3, positions=neg)


def test_an_edited_asset_is_built_again(tmp_path):
    asset = tmp_path / "quad.xml"
    asset.write_text(QUADROTOR_XML.read_text())
    first = build_world(n_drones=1, asset=asset)
    text = QUADROTOR_XML.read_text()
    assert 'name="hub" type="box" size="0.06 ' in text
    asset.write_text(text.replace('name="hub" type="box" size="0.06 ', 'name="hub" type="box" size="0.07 ', 1))
    second = build_world(n_drones=1, asset=asset)
    assert model_bytes(second.model) != model_bytes(first.model)
    assert model_bytes(second.model) == fresh(n_drones=1, asset=asset)


def test_the_cache_keeps_at_most_its_size():
    for k in range(WORLD_CACHE_SIZE + 3):
        build_world(n_drones=1, positions=[[0.0, 0.0, 0.1 * k]])
    assert len(world_mod._BUILT) == WORLD_CACHE_SIZE
