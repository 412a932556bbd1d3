"""The sensing model (swarm_mj/sensing/, docs/sensing.md): the parameters and presets, bad values,
the perfect channel as the truth bit for bit (hypothesis), seeds, range masking and the
measurement-robust margin against a hand computation. The statistics of the channel are
test_sensing_stats.py's."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.stats import chi

from swarm_mj.errors import UserError
from swarm_mj.formation.separation import seen_within
from swarm_mj.sensing import (
    FIELDS,
    PRESETS,
    TABLE_KEYS,
    Channel,
    SensingParams,
    age_bound,
    lost_in_a_row,
    noise_quantile,
    parse_sensing_table,
    robust_margin,
    sensing_preset,
)

ROOT = Path(__file__).resolve().parents[2]
T = 0.01


def _bits(a: np.ndarray) -> np.ndarray:
    """The float64 array's bit patterns (equality of these is equality bit for bit, −0.0 included)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


# --- the parameters -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(PRESETS))
def test_presets_load_and_every_field_is_in_its_range(name):
    p = sensing_preset(name)
    assert p.preset == name
    for key, meta in FIELDS.items():
        v = getattr(p, key)
        if key == "rate_hz" and v is None:
            continue
        assert meta["unit"] is not None and meta["why"]
        assert (v > meta["lo"]) if meta["open_lo"] else (v >= meta["lo"]), key
        assert (v < meta["hi"]) if meta["open_hi"] else (v <= meta["hi"]), key
    assert parse_sensing_table({"preset": name}) == p


def test_the_table_has_exactly_the_issues_keys():
    assert set(TABLE_KEYS) == {
        "preset", "position_noise_m", "velocity_noise_mps", "rate_hz", "latency_s", "packet_loss",
        "range_m", "own_position_noise_m", "own_velocity_noise_mps",
    }  # fmt: skip


def test_a_field_left_out_takes_the_presets_value():
    p = SensingParams(preset="mocap", latency_s=0.05)
    assert p.latency_s == 0.05
    assert p.position_noise_m == PRESETS["mocap"]["position_noise_m"]
    assert SensingParams() == sensing_preset("perfect")
    assert SensingParams(rate_hz=0) == SensingParams(rate_hz=None) == SensingParams()
    assert parse_sensing_table({"preset": "uwb", "rate_hz": 0}).rate_hz is None


def test_docs_table_lists_the_presets():
    """docs/sensing.md's presets table holds the code's numbers (the sources are beside it there)."""
    text = (ROOT / "docs" / "sensing.md").read_text()
    table = text.split("| key | `perfect` | `mocap` | `uwb` |\n|---|---|---|---|\n", 1)[1].split("\n\n", 1)[0]
    rows = table.splitlines()
    seen = set()
    for row in rows:
        cells = [c.strip().strip("`") for c in row.strip("|").split("|")]
        key, values = cells[0], cells[1:4]
        seen.add(key)
        for name, cell in zip(("perfect", "mocap", "uwb"), values):
            want = getattr(sensing_preset(name), key)
            want = 0.0 if want is None else want
            assert float(cell) == want, (key, name)
    assert seen == set(FIELDS)


@pytest.mark.parametrize(
    ("key", "value", "says"),
    [
        ("position_noise_m", -0.1, "must be >= 0"),
        ("position_noise_m", "2 mm", "must be a number"),
        ("velocity_noise_mps", 11.0, "<= 10"),
        ("rate_hz", -5.0, ">= 0"),
        ("latency_s", True, "must be a number"),
        ("latency_s", math.nan, "finite"),
        ("latency_s", 2.5, "<= 2"),
        ("packet_loss", 1.0, "< 1"),
        ("range_m", 0.0, "> 0"),
        ("range_m", -math.inf, "finite"),
        ("own_position_noise_m", math.inf, "finite"),
        ("own_velocity_noise_mps", -1, ">= 0"),
        ("preset", "gps", "unknown preset"),
    ],
)
def test_bad_values_are_refused_with_one_line_naming_the_key(key, value, says):
    with pytest.raises(UserError) as table_err:
        parse_sensing_table({key: value}, where="s.toml: sensing")
    msg = str(table_err.value)
    assert "\n" not in msg and f"s.toml: sensing.{key}: " in msg and says in msg, msg
    with pytest.raises(UserError) as record_err:
        SensingParams(**{key: value})
    assert "\n" not in str(record_err.value) and str(record_err.value).startswith(f"{key}: ")


def test_unknown_keys_and_a_non_table_are_refused():
    with pytest.raises(UserError, match=r"^s: sensing: unknown key\(s\) noise; allowed: .*latency_s"):
        parse_sensing_table({"noise": 1.0}, where="s: sensing")
    with pytest.raises(UserError, match="must be a table"):
        parse_sensing_table([1, 2], where="sensing")


def test_the_formation_alias_maps_to_range_m():
    assert parse_sensing_table({}, formation_sensing_range=3.0).range_m == 3.0
    assert parse_sensing_table({}).range_m == math.inf
    with pytest.raises(UserError, match=r"^sensing\.range_m: set range_m or its alias"):
        parse_sensing_table({"range_m": 2.0}, formation_sensing_range=3.0)
    with pytest.raises(UserError, match=r"^formation\.sensing_range: must be > 0"):
        parse_sensing_table({}, formation_sensing_range=-1.0)


# --- the perfect channel is the truth -----------------------------------------------------------

_ZEROED = [
    SensingParams(),
    SensingParams(rate_hz=0.0),
    # mocap's channel with its noise, latency and loss zeroed, at the control rate: perfect
    SensingParams(preset="mocap", position_noise_m=0, velocity_noise_mps=0, latency_s=0, packet_loss=0),
    SensingParams(preset="uwb", position_noise_m=0, velocity_noise_mps=0, latency_s=0, packet_loss=0, rate_hz=250),
]
_coord = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(min_value=1, max_value=8),
    which=st.integers(min_value=0, max_value=len(_ZEROED) - 1),
    data=st.data(),
)
def test_zero_noise_latency_loss_every_period_is_the_truth_bit_for_bit(n, which, data):
    ch = Channel(_ZEROED[which], T)
    ch.reset(n, seed=data.draw(st.integers(0, 2**32 - 1)), copy=data.draw(st.integers(0, 7)))
    assert ch.rng is not None
    rng_state = ch.rng.bit_generator.state
    t0 = data.draw(st.sampled_from([0.0, 3.0, 12.34]))
    for k in range(data.draw(st.integers(1, 4))):
        pos = data.draw(arrays(np.float64, (n, 3), elements=_coord))
        vel = data.draw(arrays(np.float64, (n, 3), elements=_coord))
        view = ch.observe(t0 + k * T, pos, vel)
        assert np.array_equal(_bits(view.pos), _bits(np.broadcast_to(pos, (n, n, 3))))
        assert np.array_equal(_bits(view.vel), _bits(np.broadcast_to(vel, (n, n, 3))))
        assert np.array_equal(_bits(view.own_pos), _bits(pos)) and np.array_equal(_bits(view.own_vel), _bits(vel))
        assert np.array_equal(view.mask, ~np.eye(n, dtype=bool))
        assert np.all(view.age[view.mask] == 0.0) and np.all(np.isinf(np.diag(view.age)))
    assert ch.rng.bit_generator.state == rng_state  # nothing drawn: no other stream could shift


@settings(max_examples=40, deadline=None)
@given(n=st.integers(min_value=2, max_value=8), r=st.floats(0.1, 5.0), data=st.data())
def test_with_a_range_the_perfect_mask_is_the_rules_seen_within(n, r, data):
    ch = Channel(SensingParams(range_m=r), T)
    ch.reset(n, seed=1)
    for k in range(3):
        pos = data.draw(arrays(np.float64, (n, 3), elements=st.floats(-3.0, 3.0, width=64)))
        view = ch.observe(k * T, pos, np.zeros((n, 3)))
        assert np.array_equal(view.mask, seen_within(pos, r))
        assert np.array_equal(_bits(view.pos[view.mask]), _bits(np.broadcast_to(pos, (n, n, 3))[view.mask]))


# --- seeds --------------------------------------------------------------------------------------


def _fly(params: SensingParams, seed: int, copy: int = 0, ticks: int = 60) -> list:
    n = 4
    ch = Channel(params, T)
    ch.reset(n, seed, copy)
    out = []
    for k in range(ticks):
        t = k * T
        pos = np.c_[np.arange(n) + 0.5 * t, np.sin(t + np.arange(n)), np.ones(n)]
        vel = np.c_[np.full(n, 0.5), np.cos(t + np.arange(n)), np.zeros(n)]
        out.append(ch.observe(t, pos, vel))
    return out


def _same(a: list, b: list) -> bool:
    def same_view(x, y) -> bool:
        floats = zip((x.pos, x.vel, x.age, x.own_pos), (y.pos, y.vel, y.age, y.own_pos))
        return np.array_equal(x.mask, y.mask) and all(np.array_equal(_bits(u), _bits(v)) for u, v in floats)

    return all(same_view(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize("name", ["mocap", "uwb"])
def test_same_seed_same_numbers_other_seed_or_copy_other_noise(name):
    params = SensingParams(preset=name, own_position_noise_m=0.01, own_velocity_noise_mps=0.01)
    a, b = _fly(params, 7), _fly(params, 7)
    assert _same(a, b)
    for other in (_fly(params, 8), _fly(params, 7, copy=1)):
        assert not _same(a, other)
        assert not np.array_equal(a[-1].own_pos, other[-1].own_pos)
        both = a[-1].mask & other[-1].mask
        assert both.any() and not np.array_equal(a[-1].pos[both], other[-1].pos[both])


# --- range masking ------------------------------------------------------------------------------


@pytest.mark.parametrize("latency", [0.0, 0.03])
@pytest.mark.parametrize("leader_in_range", [True, False])
def test_range_masks_on_the_true_distance_at_send_time(latency, leader_in_range):
    """Three drones: the leader at the origin, drone 1 flying away along x at 1 m/s from 1 m, drone 2
    still at (2, 0, 0); range 2.5 m. An entry is in the mask when the true distance at the send time
    (latency earlier) was under the range; the leader's column always when ``leader_in_range``."""
    r, n, delay = 2.5, 3, round(latency / T)
    ch = Channel(SensingParams(range_m=r, latency_s=latency), T, leader_in_range=leader_in_range)
    ch.reset(n, seed=3)
    still = np.array([[0.0, 0.0, 0.0], [np.nan] * 3, [2.0, 0.0, 0.0]])
    for k in range(400):
        t = k * T
        pos = still.copy()
        pos[1] = [1.0 + t, 0.0, 0.0]
        view = ch.observe(t, pos, np.zeros((n, 3)))
        if k < delay:
            assert not view.mask.any()
            continue
        ts = (k - delay) * T
        sent = still.copy()
        sent[1] = [1.0 + ts, 0.0, 0.0]
        dist = np.linalg.norm(sent[:, None, :] - sent[None, :, :], axis=-1)
        want = (dist < r) & ~np.eye(n, dtype=bool)
        if leader_in_range:
            want[1:, 0] = True
        assert np.array_equal(view.mask, want), (k, view.mask, want)
        assert np.array_equal(view.pos[want], np.broadcast_to(sent, (n, n, 3))[want])  # as sent
    assert not view.mask[0, 1]  # drone 1 is 4.99 m from the leader: out of range
    assert np.isinf(view.age[0, 1])


# --- the measurement-robust margin --------------------------------------------------------------


def test_noise_quantile_is_the_chi3_quantile():
    for c in (0.5, 0.9, 0.99, 0.999, 0.999999):
        assert noise_quantile(c) == pytest.approx(chi(3).ppf(c), rel=1e-9)


def test_lost_in_a_row_is_the_fewest_that_covers_the_confidence():
    assert lost_in_a_row(0.0, 0.999) == 0
    assert lost_in_a_row(0.1, 0.99) == 1  # 0.1² = 0.01 ≤ 0.01
    assert lost_in_a_row(0.13, 0.999) == 3  # 0.13⁴ = 2.9e-4 ≤ 1e-3 < 0.13³ = 2.2e-3
    assert lost_in_a_row(0.5, 0.9) == 3  # 0.5⁴ = 0.0625 ≤ 0.1 < 0.5³


def test_margin_against_a_hand_computation():
    """σ_p 0.01 m, σ_own 0.02 m, σ_v 0.05 m/s, 20 Hz, 25 ms, loss 0.1, T 10 ms, c 0.99, v̄ 2 m/s, ā 4 m/s²:
    k = chi₃⁻¹(0.99) = 3.3682; the broadcast gap 5 ticks, the delay ⌈2.5⌉ = 3 ticks, one loss in a row
    (0.1² ≤ 0.01): A = 0.03 + 2·0.05 − 0.01 = 0.12 s. Held: δ = k·√(0.01² + 0.02²) + 2·0.12.
    Extrapolated: δ = k·0.02236 + min(0.24, k·0.05·0.12 + 4·0.12²/2)."""
    p = SensingParams(
        position_noise_m=0.01, own_position_noise_m=0.02, velocity_noise_mps=0.05, rate_hz=20.0,
        latency_s=0.025, packet_loss=0.1,
    )  # fmt: skip
    k = 3.3682141752187276
    noise = k * math.sqrt(0.01**2 + 0.02**2)  # 0.0753156
    held = robust_margin(p, T, 2.0, confidence=0.99)
    assert held.age_s == pytest.approx(0.12, abs=1e-12) and held.lost_in_a_row == 1
    assert held.noise_m == pytest.approx(0.0753156, rel=1e-6)
    assert held.total_m == pytest.approx(noise + 0.24, rel=1e-9)
    extra = robust_margin(p, T, 2.0, accel_bound_mps2=4.0, confidence=0.99)
    assert extra.staleness_m == pytest.approx(k * 0.05 * 0.12 + 0.5 * 4.0 * 0.12**2, rel=1e-9)  # 0.0490093
    assert extra.total_m == pytest.approx(0.0753156 + 0.0490093, rel=1e-6)
    assert extra.velocity_mps == pytest.approx(k * 0.05 + 4.0 * 0.12, rel=1e-9)


def test_perfect_needs_no_margin_and_the_mocap_age_bound():
    m = robust_margin(sensing_preset("perfect"), T, 4.0, accel_bound_mps2=6.0)
    assert (m.total_m, m.age_s, m.velocity_mps) == (0.0, 0.0, 0.0)
    # mocap: 26 ms → 3 ticks, every tick, 0.13⁴ ≤ 0.001: A = 0.03 + 4·0.01 − 0.01 = 0.06 s
    assert age_bound(sensing_preset("mocap"), T, 0.999) == (pytest.approx(0.06, abs=1e-12), 3)
