"""What each drone believed, in the .rrd of ``swarm-mj run --sensing mocap`` (issue 49, "The recording";
swarm_mj/output/recording_views.py): read back with Rerun's own reader and compared with the run log's
views flown again with the same seed; under ``perfect`` the recording has none of it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
pytest.importorskip("datafusion")  # rerun-sdk[catalog]: reading a recording back needs it

from swarm_mj.cli import main as cli_main  # noqa: E402
from swarm_mj.experiments.runner import run  # noqa: E402
from swarm_mj.scenario import load_scenario  # noqa: E402

DURATION = 3.0
SEED = 3
RANGE_M = 2.5  # the circle's followers start up to 6 m apart: pairs out of range, then in range
FAR_M = 1.0e3  # an "unseen" entry sits about 1e6 m away (sensing.stage.UNSEEN_M); no drone flies this far


def read_rrd(path: Path):
    """All columns of a recording on the sim_time index, as a pandas DataFrame (as test_recording.py)."""
    with rr.server.Server(datasets={"ds": [str(path)]}) as server:
        client = server.client()  # keep every object alive until the query has run
        df = client.get_dataset("ds").reader(index="sim_time").to_pandas()
    return df


def _record(d: Path, sensing: str):
    """The bundled circle with a sensing range, flown by ``swarm-mj run`` into a recording, and by
    runner.run with the same seed for its log."""
    from swarm_mj.resources import SCENARIOS_DIR

    text = (
        (SCENARIOS_DIR / "circle.toml")
        .read_text()
        .replace("diameter = 1.0", f"diameter = 1.0\nsensing_range = {RANGE_M}")
    )
    assert f"sensing_range = {RANGE_M}" in text
    scenario = d / "circle_range.toml"
    scenario.write_text(text)
    out = d / f"circle_{sensing}.rrd"
    args = ["run", str(scenario), "--duration", str(DURATION), "--seed", str(SEED), "--sensing", sensing]
    assert cli_main([*args, "-o", str(out), "--quiet"]) == 0
    sc = load_scenario(scenario).with_overrides(sensing=sensing)
    result = run(sc, duration=DURATION, seed=SEED, progress=False)
    assert result.error is None
    return out, read_rrd(out), result


@pytest.fixture(scope="module")
def mocap(tmp_path_factory):
    return _record(tmp_path_factory.mktemp("views"), "mocap")


@pytest.fixture(scope="module")
def perfect(tmp_path_factory):
    return _record(tmp_path_factory.mktemp("views"), "perfect")


def _held(views, k: int, i: int, j: int) -> bool:
    """Whether drone i held a message from j at sample k, from the log alone (mask and in range)."""
    return bool(views.mask[k, i, j]) and abs(float(views.pos[k, i, j, 0])) < FAR_M


def _rows(df, column: str) -> list[np.ndarray]:
    """One (m, ...) float array per sample of a batch column; m = 0 where the batch is empty or absent."""
    out = []
    for v in df[column]:
        if v is None or (isinstance(v, float) and np.isnan(v)) or len(v) == 0:
            out.append(np.zeros((0,)))
        else:
            out.append(np.stack([np.asarray(x, dtype=np.float64) for x in v]))
    return out


def test_views_are_logged_and_the_timeline_is_the_run_log(mocap):
    _, df, result = mocap
    assert result.log.views is not None
    t = df["sim_time"].to_numpy().astype("timedelta64[ns]").astype(np.int64) / 1e9
    np.testing.assert_allclose(t, result.log.t, atol=1e-9)


def test_ghosts_are_where_each_observer_believed_the_others_were(mocap):
    """Per observer i and sample k: one ghost per drone j ≠ i that i held a message from, at
    views.pos[k, i, j], its class id j (the annotation context names it); none for i itself."""
    _, df, result = mocap
    log, views = result.log, result.log.views
    n, K = len(log.names), len(log.t)
    errors = []
    for i, name in enumerate(log.names):
        pos = _rows(df, f"/world/views/{name}/ghosts:Points3D:positions")
        ids = _rows(df, f"/world/views/{name}/ghosts:Points3D:class_ids")
        assert len(pos) == K
        for k in range(K):
            want = [j for j in range(n) if j != i and _held(views, k, i, j)]
            assert len(pos[k]) == len(want) and [int(c) for c in ids[k]] == want, (name, k)
            if want:
                np.testing.assert_allclose(pos[k], views.pos[k, i, want], rtol=2e-7, atol=1e-6)
                errors.extend(np.linalg.norm(pos[k] - log.pos[k, want], axis=1))
    # the ghosts are beliefs, not the truth: off by mocap's noise and delay (millimetres), never 0
    errors = np.asarray(errors)
    assert 0.3 * K * n * (n - 1) < errors.size < K * n * (n - 1)  # many pairs held a message, not all
    assert 0.0 < np.median(errors) < 0.05 and errors.min() > 0.0


def test_each_ghost_is_labelled_by_the_drone_it_stands_for(mocap):
    _, df, result = mocap
    col = next(c for c in df.columns if c.startswith("/world/views:AnnotationContext"))
    ctx = df[col].dropna().iloc[-1]
    labels = {int(e["class_id"]): e["class_description"]["info"]["label"] for e in ctx[0]}
    assert labels == dict(enumerate(result.log.names))


def test_each_follower_has_a_line_to_its_ghost_of_the_leader(mocap):
    _, df, result = mocap
    log, views = result.log, result.log.views
    for i, name in enumerate(log.names[1:], start=1):
        strips = df[f"/world/views/{name}/leader_link:LineStrips3D:strips"]
        for k, v in enumerate(strips):
            if not _held(views, k, i, 0):
                assert v is None or len(v) == 0, (name, k)
                continue
            line = np.stack([np.asarray(p, dtype=np.float64) for p in v[0]])
            np.testing.assert_allclose(line, [log.pos[k, i], views.pos[k, i, 0]], rtol=2e-7, atol=1e-6)
    assert not any(c.startswith("/world/views/leader/leader_link") for c in df.columns)


def test_age_series_of_every_pair(mocap):
    """views/<i>/age/<j>: the age of what i held from j, at every sample where it held something."""
    _, df, result = mocap
    log, views = result.log, result.log.views
    gaps = 0
    for i, a in enumerate(log.names):
        for j, b in enumerate(log.names):
            column = f"/views/{a}/age/{b}:Scalars:scalars"
            age = views.age[:, i, j]
            finite = np.isfinite(age)
            if i == j or not finite.any():
                assert column not in df.columns
                continue
            got = np.array([np.nan if v is None else float(v[0]) for v in df[column]])
            np.testing.assert_allclose(got[finite], age[finite], rtol=1e-12)
            assert np.isnan(got[~finite]).all(), (a, b)
            gaps += int((~finite).sum())
    assert gaps > 0  # the pairs out of range have no age: no sample there


def test_blueprint_shows_one_observer_and_plots_its_ages(mocap):
    from swarm_mj.output.recording import blueprint

    _, _, result = mocap
    names = result.log.names
    bp = blueprint(names, views_period_s=result.scenario.control_period)
    view3d = bp.root_container.contents[0]
    hidden = {p for p, o in view3d.visualizer_overrides.items() if isinstance(o, rr.blueprint.EntityBehavior)}
    assert hidden == {f"/world/views/{nm}" for nm in names if nm != names[1]}  # the first follower's shown
    for nm in names:  # the ghosts are drawn at the time cursor, not as the 10-s trail
        assert isinstance(view3d.visualizer_overrides[f"/world/views/{nm}/ghosts"], rr.blueprint.VisibleTimeRanges)
    tabs = bp.root_container.contents[1].contents[2].contents
    ages = [v for v in tabs if getattr(v, "origin", None) == "/views"]
    assert len(ages) == 1
    assert set(ages[0].visualizer_overrides) == {f"/views/{nm}" for nm in names if nm != names[1]}


def test_perfect_records_no_views_and_the_same_other_entities(mocap, perfect):
    _, df_m, _ = mocap
    _, df_p, result = perfect
    assert result.log.views is None

    def entities(df):
        return {c.split(":")[0] for c in df.columns if c.startswith("/")} - {"/plots/anti_collision"}

    views = {e for e in entities(df_m) if e.startswith(("/world/views", "/views/"))}
    assert views and not any(e.startswith(("/world/views", "/views")) for e in entities(df_p))
    assert entities(df_m) - views == entities(df_p)
    from swarm_mj.output.recording import _views_period, blueprint

    assert _views_period(result) is None
    bp = blueprint(result.log.names, views_period_s=_views_period(result))
    assert not bp.root_container.contents[0].visualizer_overrides
    assert not any(getattr(v, "origin", None) == "/views" for v in bp.root_container.contents[1].contents[2].contents)
