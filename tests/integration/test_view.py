"""``swarm-mj view`` and ``run --web/--spawn`` (issue 19, issue 16 item 10): the recording in the
desktop viewer or served to a browser, never a hang, and an end-to-end check in headless Chromium.

Every subprocess runs with a timeout (a hang guard, not a speed claim) and every server started
here is stopped in a ``finally``. The browser test (marker ``browser``) needs Debian's chromium:
it is installed by the session fixture where it is missing and ``CI=true`` or
``SWARM_MJ_INSTALL_BROWSER=1``; elsewhere that test is skipped with the reason.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from swarm_mj.output import viewer

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "swarm_mj.cli"]
CHROMIUM = Path("/usr/bin/chromium")
HANG_GUARD_S = 120  # subprocess timeouts: a hang fails the test instead of blocking CI
DRONES = ["leader", "follower1", "follower2", "follower3", "follower4", "follower5"]


def headless_env(**extra: str) -> dict:
    """The environment without a display (as on a server), plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(extra)
    return env


def free_port_pair(preferred: int = 9099) -> int:
    """A port p with p and p+1 free on 127.0.0.1 (``preferred`` first, as in the issue)."""
    candidates = [preferred] + list(range(20000, 20400, 7))
    for p in candidates:
        try:
            viewer.check_port(p)
        except viewer.UserError:
            continue
        return p
    pytest.skip("no free pair of local ports")


def port_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


def rerun_servers(port: int) -> list[int]:
    """PIDs of processes whose command line serves the web viewer on ``port``."""
    pids = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmd = (d / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"--web-viewer-port" in cmd and str(port).encode() in cmd:
            pids.append(int(d.name))
    return pids


def start_cli(args: list[str], env: dict | None = None, cwd: Path | None = None) -> subprocess.Popen:
    return subprocess.Popen(
        CLI + args,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env or headless_env(),
        cwd=cwd,
        preexec_fn=_default_sigint,  # Ctrl-C reaches the CLI even if this test runs in a background job
    )


def _default_sigint() -> None:
    """In the child: SIGINT at its default (a shell's background job starts with it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def wait_for_url(proc: subprocess.Popen, timeout: float = HANG_GUARD_S) -> str:
    """The URL line ``view --web`` prints once the server answers."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if "open: http://" in line:
            return line.split("open: ", 1)[1].strip()
        if not line and proc.poll() is not None:
            break
    proc.kill()
    _, err = proc.communicate(timeout=30)
    pytest.fail(f"no URL printed (rc {proc.returncode}): {err[-2000:]}")


def interrupt(proc: subprocess.Popen) -> tuple[int, str]:
    """Ctrl-C as a terminal sends it to the CLI; returns (exit status, stderr)."""
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=HANG_GUARD_S)
    return proc.returncode, err


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.communicate(timeout=30)


def assert_no_server_left(port: int) -> None:
    deadline = time.monotonic() + 10  # SIGKILL reaping can take a moment
    while (rerun_servers(port) or port_open(port) or port_open(port + 1)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not rerun_servers(port), "the rerun server outlived the CLI"
    assert not port_open(port) and not port_open(port + 1)


@pytest.fixture(scope="module")
def small_rrd(tmp_path_factory) -> Path:
    """A 2-s circle recording (enough for the serving checks)."""
    d = tmp_path_factory.mktemp("view")
    out = d / "circle2s.rrd"
    r = subprocess.run(
        CLI + ["run", "circle", "--duration", "2", "-o", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=600,
        env=headless_env(),
    )
    assert r.returncode == 0, r.stderr
    return out


# --------------------------------------------------------------------------- units


def test_find_rerun_does_not_need_path(monkeypatch):
    monkeypatch.setenv("PATH", "/nonexistent")
    exe = viewer.find_rerun()
    assert exe.is_file() and os.access(exe, os.X_OK)
    out = subprocess.run([str(exe), "--version"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "rerun" in out.stdout.lower()


def test_has_display_follows_the_environment(monkeypatch):
    if not sys.platform.startswith("linux"):
        pytest.skip("DISPLAY/WAYLAND_DISPLAY matter on Linux only")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert not viewer.has_display()
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    assert viewer.has_display()
    monkeypatch.delenv("WAYLAND_DISPLAY")
    monkeypatch.setenv("DISPLAY", ":0")
    assert viewer.has_display()


def test_web_url_points_the_page_at_the_recording_port():
    url = viewer.web_url(9099)
    assert url.startswith("http://127.0.0.1:9099/?url=")
    assert "rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9100%2Fproxy" in url


def test_check_port_refuses_a_listening_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        if busy >= 65535:
            pytest.skip("ephemeral port at the top of the range")
        with pytest.raises(viewer.UserError, match=f"port {busy} .*in use"):
            viewer.check_port(busy)
        if busy > 1:
            with pytest.raises(viewer.UserError, match=rf"port {busy} for the recording \(--port \+ 1\)"):
                viewer.check_port(busy - 1)


# --------------------------------------------------------------------------- view: no display, bad input


def test_view_without_display_says_how_in_one_line(small_rrd):
    t0 = time.monotonic()
    r = subprocess.run(
        CLI + ["view", str(small_rrd)], capture_output=True, text=True, timeout=HANG_GUARD_S, env=headless_env()
    )
    elapsed = time.monotonic() - t0
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1, r.stderr
    assert len(lines) == 1 and lines[0].startswith("swarm-mj: error: no display"), r.stderr
    assert f"swarm-mj view {small_rrd} --web" in lines[0] and f"rerun {small_rrd}" in lines[0]
    print(f"view without a display: exit {r.returncode} after {elapsed:.2f} s")  # -s shows it


@pytest.mark.parametrize("kind", ["missing", "directory"])
def test_view_bad_file_is_one_line_and_exit_2(tmp_path, kind):
    target = tmp_path / "nope.rrd" if kind == "missing" else tmp_path
    for extra in ([], ["--web"]):
        r = subprocess.run(
            CLI + ["view", str(target), *extra],
            capture_output=True,
            text=True,
            timeout=HANG_GUARD_S,
            env=headless_env(),
        )
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("swarm-mj: error:") and "Traceback" not in r.stderr


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads a mode-000 file")
def test_view_unreadable_file_is_one_line_and_exit_2(tmp_path):
    f = tmp_path / "locked.rrd"
    f.write_bytes(b"RRF2")
    f.chmod(0)
    r = subprocess.run(CLI + ["view", str(f)], capture_output=True, text=True, timeout=HANG_GUARD_S, env=headless_env())
    assert r.returncode == 2 and "cannot read" in r.stderr


def test_view_with_a_broken_display_reports_the_viewer_error(small_rrd):
    """A DISPLAY that does not answer: the viewer fails at once and that is one line, exit 1."""
    r = subprocess.run(
        CLI + ["view", str(small_rrd)],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
        env=headless_env(DISPLAY=":987"),
    )
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1, r.stderr
    assert lines[0].startswith("swarm-mj: error: the Rerun viewer failed"), r.stderr


# --------------------------------------------------------------------------- view --web


@pytest.mark.parametrize("which", [0, 1])
def test_view_web_busy_port_is_one_line_and_exit_2(small_rrd, which):
    port = free_port_pair(20500)
    with socket.socket() as s:
        s.bind(("127.0.0.1", port + which))
        s.listen()
        r = subprocess.run(
            CLI + ["view", str(small_rrd), "--web", "--port", str(port)],
            capture_output=True,
            text=True,
            timeout=HANG_GUARD_S,
            env=headless_env(),
        )
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"port {port + which}" in lines[0] and "in use" in lines[0]
    assert not rerun_servers(port)


def test_view_web_serves_the_page_and_ctrl_c_exits_130(small_rrd):
    port = free_port_pair()
    proc = start_cli(["view", str(small_rrd), "--web", "--port", str(port)])
    try:
        url = wait_for_url(proc)
        assert url == viewer.web_url(port)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as resp:
            html = resp.read().decode()
            assert resp.status == 200
        assert "re_viewer.js" in html  # Rerun's web viewer, served by the bundled binary
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/re_viewer_bg.wasm", timeout=60) as resp:
            assert resp.status == 200 and len(resp.read()) > 1_000_000
        assert port_open(port + 1)  # the recording's gRPC proxy
        assert len(rerun_servers(port)) == 1
        rc, err = interrupt(proc)
    finally:
        stop(proc)
    assert rc == 130, err
    assert "Traceback" not in err and err.strip().splitlines() == ["swarm-mj: interrupted"]
    assert_no_server_left(port)


def test_view_web_sigterm_also_stops_the_server(small_rrd):
    port = free_port_pair(20600)
    proc = start_cli(["view", str(small_rrd), "--web", "--port", str(port)])
    try:
        wait_for_url(proc)
        proc.terminate()
        _, err = proc.communicate(timeout=HANG_GUARD_S)
    finally:
        stop(proc)
    assert proc.returncode == 130 and "Traceback" not in err
    assert_no_server_left(port)


# --------------------------------------------------------------------------- run --web / --spawn


def test_run_web_refuses_no_record_and_a_busy_port_before_flying(tmp_path):
    r = subprocess.run(
        CLI + ["run", "circle", "--no-record", "--web"],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
        env=headless_env(),
        cwd=tmp_path,
    )
    assert r.returncode == 2 and "--no-record" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    port = free_port_pair(20700)
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))
        s.listen()
        r = subprocess.run(
            CLI + ["run", "circle", "-o", "c.rrd", "--web", "--port", str(port)],
            capture_output=True,
            text=True,
            timeout=HANG_GUARD_S,
            env=headless_env(),
            cwd=tmp_path,
        )
    assert r.returncode == 2 and "in use" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "c.rrd").exists()  # refused before the run


@pytest.mark.slow
def test_run_web_serves_after_the_run(tmp_path):
    port = free_port_pair(20800)
    out = tmp_path / "c.rrd"
    proc = start_cli(["run", "circle", "--duration", "2", "-o", str(out), "--quiet", "--web", "--port", str(port)])
    try:
        url = wait_for_url(proc, timeout=600)
        assert out.stat().st_size > 0  # written before serving
        with urllib.request.urlopen(url, timeout=30) as resp:
            assert resp.status == 200
        rc, err = interrupt(proc)
    finally:
        stop(proc)
    assert rc == 130 and "Traceback" not in err, err
    assert_no_server_left(port)


@pytest.mark.slow
def test_run_spawn_headless_keeps_the_recording_and_exits_0(tmp_path):
    """Issue 16 item 10: no display and the venv's bin/ not on PATH: a one-line note, exit 0."""
    out = tmp_path / "c.rrd"
    env = headless_env(PATH="/usr/bin:/bin")
    r = subprocess.run(
        CLI + ["run", "circle", "--duration", "2", "-o", str(out), "--quiet", "--spawn"],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 0 and not out.with_name("c.rrd.partial").exists()
    notes = [ln for ln in r.stderr.splitlines() if "no display" in ln]
    assert len(notes) == 1 and "the recording is kept" in notes[0] and "Traceback" not in r.stderr


# --------------------------------------------------------------------------- the browser


def _load_tool():
    spec = importlib.util.spec_from_file_location("screenshot_viewer", ROOT / "tools" / "screenshot_viewer.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def chromium() -> Path:
    """Debian's chromium; installed with apt-get where it is missing and CI=true or
    SWARM_MJ_INSTALL_BROWSER=1 (root or passwordless sudo), else the test is skipped."""
    pytest.importorskip("playwright.sync_api", reason="playwright is in the test extra: pip install -e '.[test]'")
    if CHROMIUM.exists():
        return CHROMIUM
    if not (os.environ.get("CI", "").lower() == "true" or os.environ.get("SWARM_MJ_INSTALL_BROWSER") == "1"):
        pytest.skip(
            f"{CHROMIUM} is missing: apt-get install chromium, or set SWARM_MJ_INSTALL_BROWSER=1 "
            "(or CI=true) to let the test set-up install it"
        )
    apt = shutil.which("apt-get")
    if apt is None:
        pytest.skip("no apt-get to install chromium with")
    sudo = [] if os.geteuid() == 0 else ["sudo", "-n"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in (["update", "-qq"], ["install", "-y", "-qq", "chromium"]):
        r = subprocess.run(sudo + [apt, *cmd], capture_output=True, text=True, timeout=900, env=env)
        if r.returncode != 0:
            pytest.fail(f"apt-get {' '.join(cmd)} failed: {r.stderr[-1500:]}")
    assert CHROMIUM.exists()
    return CHROMIUM


@pytest.mark.browser
@pytest.mark.slow
def test_browser_loads_the_recording_and_shows_the_drones(tmp_path, chromium):
    """``swarm-mj view circle.rrd --web --port 9099`` in headless Chromium (WebGL on the CPU via
    SwiftShader): the page's viewer holds the recording (app id and the drones' entity paths,
    read from the viewer's own copy), the screenshot is not blank, and the 3D view's region shows
    the drones' colours (recording.LEADER_COLOR red, FOLLOWER_COLOR blue)."""
    tool = _load_tool()
    rrd = tmp_path / "circle.rrd"
    r = subprocess.run(
        CLI + ["run", "circle", "--duration", "20", "-o", str(rrd), "--quiet"],
        capture_output=True,
        text=True,
        timeout=900,
        env=headless_env(),
    )
    assert r.returncode == 0, r.stderr
    port = free_port_pair(9099)
    png, page_rrd = tmp_path / "viewer.png", tmp_path / "page.rrd"
    proc = start_cli(["view", str(rrd), "--web", "--port", str(port)])
    try:
        url = wait_for_url(proc)
        info = tool.shoot(
            url, png, page_rrd=page_rrd, expected_bytes=rrd.stat().st_size, timeout=300, chromium=str(chromium)
        )
        rc, err = interrupt(proc)
    finally:
        stop(proc)
    print(info)
    assert "error" not in info, info
    assert rc == 130 and "Traceback" not in err
    assert_no_server_left(port)
    # the page loaded the recording: what the viewer holds names the app and every drone
    contents = tool.rrd_contents(page_rrd)
    assert contents["rc"] == 0
    assert "swarm-mj" in contents["application_ids"]
    for name in DRONES:
        assert f"/world/drones/{name}" in contents["entities"], name
    # the screenshot is not blank
    whole = tool.pixel_stats(png)
    print("screenshot", whole)
    assert whole["grey_std"] > 10 and whole["distinct_colours"] > 200, whole
    # the 3D view shows the drones: their colours cover part of the view's region, and it varies
    w, h = whole["shape"][1], whole["shape"][0]
    view3d = tool.pixel_stats(png, tool.region_3d(w, h))
    print("3D view", view3d)
    assert view3d["grey_std"] > 10, view3d
    assert view3d["leader_red_fraction"] > 1e-3 and view3d["follower_blue_fraction"] > 1e-3, view3d


# --------------------------------------------------------------------------- what the 3D view shows


def test_slot_markers_follow_the_logged_slots(small_rrd):
    """The 3D view draws each slot as a dot under a moving transform (world/slot_markers), so the
    10-s trails stay visible; the dot must sit on the slot that world/slots logs at every sample."""
    import numpy as np

    rr = pytest.importorskip("rerun")
    pytest.importorskip("datafusion")
    with rr.server.Server(datasets={"ds": [str(small_rrd)]}) as server:
        client = server.client()
        df = client.get_dataset("ds").reader(index="sim_time").to_pandas()
    slots = np.array([np.stack(list(v)).astype(np.float64) for v in df["/world/slots:Points3D:positions"]])
    assert slots.ndim == 3 and slots.shape[1:] == (5, 3)
    for j, name in enumerate(DRONES[1:]):
        tr = np.array(
            [np.stack(list(v)).astype(np.float64) for v in df[f"/world/slot_markers/{name}:Transform3D:translation"]]
        )[:, 0]
        np.testing.assert_allclose(tr, slots[:, j], atol=1e-6)
    from swarm_mj.output.recording import blueprint

    view3d = blueprint(DRONES).root_container.contents[0]
    assert isinstance(view3d, rr.blueprint.Spatial3DView)
    assert "- /world/slots" in view3d.contents and "+ /world/**" in view3d.contents


def test_pixel_stats_tell_a_drone_from_an_empty_view(tmp_path):
    """The browser test's measure can fail: an empty (white) 3D view has no variance and none of
    the drones' colours; a patch of the leader's red and the followers' blue is counted."""
    import numpy as np
    from PIL import Image

    tool = _load_tool()
    img = np.full((100, 200, 3), 255, np.uint8)
    Image.fromarray(img).save(tmp_path / "white.png")
    s = tool.pixel_stats(tmp_path / "white.png")
    assert s["grey_std"] == 0 and s["leader_red_fraction"] == 0 and s["follower_blue_fraction"] == 0
    img[10:20, 10:30] = (220, 40, 40)  # 200 px of recording.LEADER_COLOR
    img[50:60, 100:150] = (40, 110, 220)  # 500 px of recording.FOLLOWER_COLOR
    Image.fromarray(img).save(tmp_path / "drones.png")
    s = tool.pixel_stats(tmp_path / "drones.png")
    assert s["leader_red_fraction"] == pytest.approx(200 / 20000)
    assert s["follower_blue_fraction"] == pytest.approx(500 / 20000)
    box = tool.pixel_stats(tmp_path / "drones.png", (0, 0, 100, 100))  # only the red patch inside
    assert box["shape"] == [100, 100] and box["follower_blue_fraction"] == 0 and box["leader_red_fraction"] > 0
