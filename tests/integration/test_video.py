"""Headless video and still export (issue 7): ``swarm_mj.video``, ``swarm-mj video``, ``run --video/--snapshot``.

What is checked, and against what:

* the MP4 is decoded back with imageio's FFMPEG plugin (imageio-ffmpeg's own ffmpeg):
  codec, frame rate and size from the container, and the number of frames by counting the
  decoded frames. The count is exactly round(duration·fps) by construction
  (``frame_times``: frame i shows t0 + i/fps, i < round(duration·fps)); x264 neither drops
  nor duplicates frames of a constant-rate input, so no ±1 is allowed here (a player that
  reads ``duration`` from the metadata may still show the last frame's end differently);
* that the frames show the drones where the *log* says they are: the logged positions are
  projected through the camera MuJoCo drew with (``project_points`` on the renderer's
  ``mjvGLCamera``), and that projection is itself checked against MuJoCo's segmentation
  rendering (the pixels of each drone's geoms); then the decoded pixels around the
  projected leader are red and those around followers blue;
* a missing EGL: one line on stderr naming the cause and the fix, exit status 1, and the
  recording still written. Two real failures are produced in a subprocess: an EGL loader
  with no driver (GLVND told to look for vendor files in an empty place: what a machine
  without libegl-mesa0 looks like) and no libEGL.so.1 at all (the dynamic loader's
  "cannot open shared object file" raised where PyOpenGL opens it). The in-process test
  replaces the renderer factory with one raising PyOpenGL's own exception;
* a MUJOCO_GL backend that cannot load (``osmesa`` without libOSMesa, which makes ``import
  mujoco`` itself fail): the run still flies and its recording is written, the still gives one
  line and exit status 1 (issue 16 item 11).

Rendering-dependent tests are marked ``egl`` (deselect with ``-m 'not egl'``).
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported (swarm_mj does the same)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import textwrap  # noqa: E402

import imageio.v3 as iio  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from swarm_mj import cli, video  # noqa: E402
from swarm_mj.errors import RenderError, UserError
from swarm_mj.experiments.runner import run
from swarm_mj.video import gl as video_gl  # noqa: E402

LEADER = np.array(video.LEADER_RGB) * 255
FOLLOWER = np.array(video.FOLLOWER_RGB) * 255


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def short_run():
    """3 s of the circle: the drones take off and spread to their layers (the layered rule: the
    checks below were laid out on its positions at 3 s, no drone hidden behind another)."""
    r = run("circle", duration=3.0, progress=False, anti_collision="layers")
    assert r.error is None
    return r


@pytest.fixture(scope="module")
def circle20():
    """The circle up to t = 20 s (formation settled around the leader)."""
    r = run("circle", duration=20.0, progress=False)
    assert r.error is None
    return r


def _drone_pixels(seg: np.ndarray, world, i: int) -> np.ndarray:
    """(m, 2) pixel coordinates (x, y) of drone i's geoms and drawn sites (hub, rotor discs, nose:
    assets/quadrotor.xml) in a segmentation image."""
    geoms = np.flatnonzero(world.geom_drone == i)
    sites = np.flatnonzero(world.model.site_bodyid == world.body_ids[i])
    mask = (np.isin(seg[..., 0], geoms) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM))) | (
        np.isin(seg[..., 0], sites) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_SITE))
    )
    ys, xs = np.nonzero(mask)
    return np.column_stack([xs, ys])


def _window(img: np.ndarray, xy: np.ndarray, r: int) -> np.ndarray:
    x, y = int(round(xy[0])), int(round(xy[1]))
    return img[max(0, y - r) : y + r + 1, max(0, x - r) : x + r + 1].reshape(-1, 3).astype(float)


def _closest_colour_share(pixels: np.ndarray, colour: np.ndarray, other: np.ndarray) -> float:
    """Share of pixels closer to ``colour`` than to ``other`` and saturated (not floor grey)."""
    d_c = np.linalg.norm(pixels - colour, axis=1)
    d_o = np.linalg.norm(pixels - other, axis=1)
    sat = pixels.max(axis=1) - pixels.min(axis=1)
    return float(np.mean((d_c < d_o) & (sat > 60)))


# --------------------------------------------------------------------------- options (no rendering)


def _args(**kw) -> argparse.Namespace:
    base = dict(video=None, snapshot=None, snapshot_time=20.0, fps=30, size="1280x720", duration=25.0)
    base.update(kw)
    return argparse.Namespace(**base)


def test_parse_size():
    assert video.parse_size("1280x720") == (1280, 720)
    assert video.parse_size(" 320 X 240 ") == (320, 240)
    for bad in ("1280", "1280x", "x720", "12.5x10", "-320x240", "0x0", "99999x10", "abc"):
        with pytest.raises(UserError):
            video.parse_size(bad)


def test_check_video_args_rejects_bad_options(tmp_path):
    ok = tmp_path / "a.mp4"
    video.check_video_args(_args(video=str(ok), snapshot=str(tmp_path / "a.png")))  # fine
    bad = [
        _args(video=str(ok), fps=0),
        _args(video=str(ok), fps=-5),
        _args(video=str(ok), size="1280*720"),
        _args(video=str(ok), size="321x240"),  # odd: H.264 4:2:0 needs even
        _args(video=str(tmp_path / "a.avi")),
        _args(video=str(tmp_path / "missing" / "a.mp4")),
        _args(snapshot=str(tmp_path / "a.jpg")),
        _args(snapshot=str(tmp_path / "a.png"), snapshot_time=30.0),  # after the end (25 s)
        _args(snapshot=str(tmp_path / "a.png"), snapshot_time=-1.0),
    ]
    for a in bad:
        with pytest.raises(UserError):
            video.check_video_args(a)


def test_bad_options_exit_2_before_simulating(tmp_path, capsys):
    rc = cli.main(["run", "circle", "--no-record", "--quiet", "--video", str(tmp_path / "nope" / "v.mp4")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("swarm-mj: error: --video")
    rc = cli.main(
        ["video", "circle", "-o", str(tmp_path / "v.mp4"), "--snapshot", str(tmp_path / "s.png"), "--duration", "5"]
    )  # default still time 20 s > 5 s
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--snapshot-time" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_frame_times_and_nearest_sample():
    ts = video.frame_times(0.0, 3.0, 10)
    assert len(ts) == 30 and ts[0] == 0.0 and np.allclose(np.diff(ts), 0.1)
    assert len(video.frame_times(0.0, 25.0, 30)) == 750
    assert len(video.frame_times(2.0, 2.04, 30)) == 1
    t = np.arange(0, 1.0001, 0.01)
    assert video.nearest_index(t, 0.504) == 50
    assert video.nearest_index(t, 0.506) == 51
    assert video.nearest_index(t, -3.0) == 0 and video.nearest_index(t, 9.0) == len(t) - 1


def test_camera_path_keeps_every_drone_in_frame(circle20):
    """The framing rule alone (no rendering): every logged drone inside the margin, all run long."""
    log = circle20.log
    style = video.VideoStyle()
    aspect = 16 / 9
    cam = video.CameraPath.frame_swarm(log.t, log.pos, aspect, style)
    ty = np.tan(np.radians(style.fovy_deg) / 2)
    tx = ty * aspect
    for j in range(0, len(log.t), 7):
        fwd, right, up = video.camera_axes(cam.azimuth[j], cam.elevation)
        eye = cam.lookat[j] - cam.distance[j] * fwd
        rel = log.pos[j] - eye
        z = rel @ fwd
        assert (z > 0).all()
        assert (np.abs(rel @ right) / z <= tx * (1 - style.margin) + 1e-9).all()
        assert (np.abs(rel @ up) / z <= ty * (1 - style.margin) + 1e-9).all()
    assert cam.distance.min() >= style.min_distance


def test_missing_egl_message_names_cause_and_fix(monkeypatch):
    monkeypatch.setattr(video_gl, "mujoco_gl_backend", lambda: "egl")
    msg = video.describe_gl_failure(
        ImportError(
            "Unable to load EGL library", "libEGL.so.1: cannot open shared object file: No such file or directory"
        )
    )
    assert "\n" not in msg and "libEGL.so.1 is not installed" in msg and "apt-get install libegl1" in msg
    msg = video.describe_gl_failure(
        ImportError(
            "Cannot initialize a EGL device display. This likely means that your EGL driver does not support "
            "the PLATFORM_DEVICE extension, which is\n required for creating a headless rendering context."
        )
    )
    assert "\n" not in msg and "no driver" in msg and "libegl-mesa0" in msg and "libgl1-mesa-dri" in msg


# --------------------------------------------------------------------------- rendering


@pytest.mark.egl
def test_video_decodes_with_the_drones_where_the_log_says(short_run, tmp_path, capsys):
    out = tmp_path / "circle.mp4"
    fps, (w, h), d = 10, (320, 240), 3.0
    # Without trails, markers and caption (they are drawn from the log, not from the replayed
    # model): what is red or blue on screen is then the drones' own geoms, placed by qpos.
    plain = video.VideoStyle(trails=False, reference=False, markers=False, caption=False)
    video.render_video(short_run, out, fps=fps, size=(w, h), progress=True, style=plain)
    assert f"{round(d * fps)}/{round(d * fps)} frames" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["circle.mp4"]  # no partial file left

    meta = iio.immeta(out, plugin="FFMPEG")
    assert meta["codec"] == "h264" and meta["fps"] == pytest.approx(fps) and tuple(meta["size"]) == (w, h)
    frames = np.stack(list(iio.imiter(out, plugin="FFMPEG")))
    assert frames.shape == (round(d * fps), h, w, 3)
    assert (frames.reshape(len(frames), -1, 3).std(axis=1).mean(axis=1) > 8).all(), "a blank frame"

    times = video.frame_times(0.0, d, fps)
    where = {}
    with video.Replay(short_run.log, width=w, height=h, style=plain) as rep:
        for f in (0, len(times) - 1):
            seg = rep.render(times[f], segmentation=True)
            j = rep.last_index
            assert abs(short_run.log.t[j] - times[f]) <= 0.005 + 1e-9
            px = video.project_points(rep.glcamera, short_run.log.pos[j], w, h)
            assert np.isfinite(px).all() and (px[:, 0] > 0).all() and (px[:, 0] < w).all()
            assert (px[:, 1] > 0).all() and (px[:, 1] < h).all()
            for i in range(len(px)):
                pix = _drone_pixels(seg, rep.world, i)
                assert len(pix) > 20, (f, i)
                # the replayed model put drone i where the log says (the silhouette's median sits
                # off its centre's projection by a few pixels when the drone is tilted, as it is
                # while crossing at t ≈ 3 s) ...
                assert np.linalg.norm(np.median(pix, axis=0) - px[i]) < 4, (f, i)
                # ... and the decoded video shows it there, in its colour (leader red, followers blue)
                seen = frames[f][pix[:, 1], pix[:, 0]].astype(float)
                own, other = (LEADER, FOLLOWER) if i == 0 else (FOLLOWER, LEADER)
                assert _closest_colour_share(seen, own, other) > 0.5, (f, i)
                assert _closest_colour_share(seen, other, own) < 0.05, (f, i)
            where[f] = px
    # the drones moved on screen between the first and last frame
    moved = np.linalg.norm(where[len(times) - 1] - where[0], axis=1)
    assert (moved > 10).all(), moved


@pytest.mark.egl
def test_projection_matches_what_mujoco_draws():
    """project_points against MuJoCo's own segmentation image of a small sphere, to a pixel."""
    xml = """<mujoco><statistic extent="10"/><visual><global offwidth="640" offheight="360"/></visual>
             <worldbody><body name="b" mocap="true"><geom type="sphere" size="0.04"/></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    w, h = 640, 360
    r = video.open_renderer(m, w, h)
    try:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = (0.3, -0.2, 1.0)
        cam.distance, cam.azimuth, cam.elevation = 5.0, 125.0, -38.0
        for p in [(0.3, -0.2, 1.0), (1.0, 0.0, 0.0), (-1.0, -0.5, 1.5), (1.5, 1.0, 0.2), (-0.5, 1.2, 2.0)]:
            d.mocap_pos[0] = p
            mujoco.mj_forward(m, d)
            r.update_scene(d, cam)
            r.enable_segmentation_rendering()
            seg = r.render()
            r.disable_segmentation_rendering()
            ys, xs = np.nonzero(seg[..., 0] == 0)
            assert len(xs) > 10
            px = video.project_points(
                mujoco.mjv_averageCamera(r.scene.camera[0], r.scene.camera[1]), np.array([p]), w, h
            )[0]
            # pixel i covers [i, i + 1): the centre of the drawn disc is at mean index + 0.5
            assert np.allclose(px, (xs.mean() + 0.5, ys.mean() + 0.5), atol=1.0), (p, px)
    finally:
        r.close()


@pytest.mark.egl
def test_snapshot_at_20s_shows_the_six_drones(circle20, tmp_path):
    w, h = 640, 360
    png = tmp_path / "swarm.png"
    video.render_snapshot(circle20, png, time=20.0, size=(w, h))
    img = iio.imread(png)
    assert img.shape == (h, w, 3)
    with video.Replay(circle20.log, width=w, height=h) as rep:
        seg = rep.render(20.0, segmentation=True)
        j = rep.last_index
        assert circle20.log.t[j] == pytest.approx(20.0)
        px = video.project_points(rep.glcamera, circle20.log.pos[j], w, h)
        world = rep.world
    margin = 10
    assert (px[:, 0] > margin).all() and (px[:, 0] < w - margin).all(), px
    assert (px[:, 1] > margin).all() and (px[:, 1] < h - margin).all(), px
    for i in range(6):
        pix = _drone_pixels(seg, world, i)
        assert len(pix) > 100, f"drone {i} barely visible"
        # MuJoCo drew drone i around where the projection puts its centre of mass
        assert np.linalg.norm(np.median(pix, axis=0) - px[i]) < 5, (i, np.median(pix, axis=0), px[i])
        colour, other = (LEADER, FOLLOWER) if i == 0 else (FOLLOWER, LEADER)
        assert _closest_colour_share(_window(img, px[i], 3), colour, other) > 0.3, i
    # a pentagon around the leader: the followers' angles about the leader are 72 degrees apart on screen
    # (projected, so only their order is checked): all five lie on different sides of the leader
    ang = np.sort(np.arctan2(*(px[1:] - px[0]).T[::-1]))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
    assert gaps.max() < np.pi, "followers not around the leader on screen"


@pytest.mark.egl
def test_cli_video_and_run_snapshot(tmp_path, capsys):
    mp4 = tmp_path / "v.mp4"
    rc = cli.main(["video", "circle", "--duration", "2", "--fps", "10", "--size", "160x120", "-o", str(mp4), "--quiet"])
    assert rc == 0
    assert sum(1 for _ in iio.imiter(mp4, plugin="FFMPEG")) == 20
    png, rrd = tmp_path / "s.png", tmp_path / "s.rrd"
    rc = cli.main(
        [
            "run",
            "circle",
            "--duration",
            "1",
            "--quiet",
            "-o",
            str(rrd),
            "--snapshot",
            str(png),
            "--snapshot-time",
            "0.5",
            "--size",
            "160x120",
        ]
    )
    assert rc == 0 and rrd.exists() and iio.imread(png).shape == (120, 160, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.png", "s.rrd", "v.mp4"]


@pytest.mark.egl
def test_failed_video_leaves_no_file_and_keeps_the_old_one(short_run, tmp_path, monkeypatch):
    out = tmp_path / "v.mp4"
    out.write_bytes(b"old video")
    calls = {"n": 0}
    real = video.Replay.render

    def failing(self, t, **kw):
        calls["n"] += 1
        if calls["n"] > 3:
            raise KeyboardInterrupt
        return real(self, t, **kw)

    monkeypatch.setattr(video.Replay, "render", failing)
    with pytest.raises(KeyboardInterrupt):
        video.render_video(short_run, out, fps=10, size=(160, 120), progress=False)
    assert out.read_bytes() == b"old video"
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


# --------------------------------------------------------------------------- missing EGL


def test_missing_egl_in_process_one_line_exit_1_recording_kept(tmp_path, monkeypatch, capsys):
    def no_egl(model, width, height):
        # what PyOpenGL's EGL platform raises when libEGL.so.1 cannot be opened
        raise ImportError(
            "Unable to load EGL library", "libEGL.so.1: cannot open shared object file: No such file or directory"
        )

    monkeypatch.setattr(video_gl, "renderer_factory", no_egl)
    monkeypatch.setattr(video_gl, "mujoco_gl_backend", lambda: "egl")
    rrd, png = tmp_path / "c.rrd", tmp_path / "c.png"
    rc = cli.main(
        [
            "run",
            "circle",
            "--duration",
            "0.5",
            "--quiet",
            "-o",
            str(rrd),
            "--snapshot",
            str(png),
            "--snapshot-time",
            "0.2",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert len(err) == 1 and err[0].startswith("swarm-mj: error: headless rendering needs EGL"), err
    assert "libEGL.so.1 is not installed" in err[0] and "apt-get install" in err[0]
    assert rrd.exists() and rrd.stat().st_size > 0 and not png.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.rrd"]
    with pytest.raises(RenderError):
        video.open_renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 64, 64)


_NO_LIBEGL = textwrap.dedent("""
    import ctypes, os, sys
    _init = ctypes.CDLL.__init__
    def _init_without_egl(self, name, *a, **kw):
        if name and os.path.basename(str(name)).startswith("libEGL"):
            raise OSError(f"{name}: cannot open shared object file: No such file or directory")
        _init(self, name, *a, **kw)
    ctypes.CDLL.__init__ = _init_without_egl
    from swarm_mj.cli import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.parametrize("case", ["no EGL driver", "no libEGL"])
def test_missing_egl_subprocess(case, tmp_path):
    """A real EGL failure in a fresh process: one line, exit 1, the recording written, no image."""
    env = dict(os.environ)
    env.pop("MUJOCO_GL", None)  # swarm_mj's default (egl) is what is under test
    env.pop("PYOPENGL_PLATFORM", None)
    env.pop("EGL_LOG_LEVEL", None)
    argv = [
        "run",
        "circle",
        "--duration",
        "0.5",
        "--quiet",
        "-o",
        "c.rrd",
        "--snapshot",
        "c.png",
        "--snapshot-time",
        "0.2",
    ]
    if case == "no EGL driver":
        env["__EGL_VENDOR_LIBRARY_DIRS"] = str(tmp_path / "no-vendors")  # GLVND finds no EGL driver
        cmd = [sys.executable, "-m", "swarm_mj.cli", *argv]
        cause = "found no driver"
    else:
        cmd = [sys.executable, "-c", _NO_LIBEGL, *argv]
        cause = "libEGL.so.1 is not installed"
    p = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    err = p.stderr.strip().splitlines()
    assert p.returncode == 1, p.stderr
    assert len(err) == 1 and err[0].startswith("swarm-mj: error: headless rendering needs EGL"), p.stderr
    assert cause in err[0] and "apt-get install libegl1" in err[0]
    assert (tmp_path / "c.rrd").exists() and not (tmp_path / "c.png").exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["c.rrd"]


_NO_OSMESA = textwrap.dedent("""
    import ctypes, sys
    _init = ctypes.CDLL.__init__
    def _init_without_osmesa(self, name, *a, **kw):
        if name and "osmesa" in str(name).lower():
            raise OSError(f"{name}: cannot open shared object file: No such file or directory")
        _init(self, name, *a, **kw)
    ctypes.CDLL.__init__ = _init_without_osmesa
    from swarm_mj.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_osmesa_that_cannot_load_is_one_line_exit_1_recording_kept(tmp_path):
    """MUJOCO_GL=osmesa without libOSMesa (hidden here even where it is installed): import mujoco
    fails inside PyOpenGL with an AttributeError. The run flies with rendering off, the recording
    is written, and the still fails in one line naming MUJOCO_GL=osmesa and the EGL fix."""
    env = dict(os.environ, MUJOCO_GL="osmesa")
    env.pop("PYOPENGL_PLATFORM", None)
    argv = [
        "run",
        "circle",
        "--duration",
        "0.5",
        "--quiet",
        "-o",
        "c.rrd",
        "--snapshot",
        "c.png",
        "--snapshot-time",
        "0.2",
    ]
    p = subprocess.run(
        [sys.executable, "-c", _NO_OSMESA, *argv], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    err = p.stderr.strip().splitlines()
    assert p.returncode == 1, p.stderr
    assert "Traceback" not in p.stderr, p.stderr
    assert len(err) == 1 and err[0].startswith(
        "swarm-mj: error: cannot render: MuJoCo could not load MUJOCO_GL=osmesa"
    ), p.stderr
    assert "MUJOCO_GL=egl" in err[0]
    assert (tmp_path / "c.rrd").stat().st_size > 0 and not (tmp_path / "c.png").exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["c.rrd"]


def test_a_run_on_solid_ground_is_replayed_with_its_landing_gear(short_run):
    """Under a preset with a solid ground (docs/aero.md) the video shows the drones the physics flew:
    each with its landing skid (a geom) and strut (a site); under the paper's physics, the plain swarm."""
    from swarm_mj.physics.aero.presets import with_aero
    from swarm_mj.video.encode import _world_of

    assert _world_of(short_run, None) is None  # Replay builds the plain swarm
    grounded = dataclasses.replace(short_run, scenario=with_aero(short_run.scenario, "realistic"))
    w = _world_of(grounded, None)
    assert w is not None and w.names == short_run.log.names
    for name in w.names:
        assert mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, f"{name}/skid") >= 0
        assert mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_SITE, f"{name}/strut") >= 0
    np.testing.assert_array_equal(w.initial_positions, short_run.log.pos[0])
    assert _world_of(grounded, short_run) is short_run  # a world passed in is used as it is
