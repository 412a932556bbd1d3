"""Open a recording (``.rrd``): the desktop Rerun viewer where a display exists, or Rerun's web
viewer served on localhost for a browser (through an SSH tunnel from a headless machine).

Both use the viewer that the ``rerun-sdk`` wheel ships (the ``rerun`` binary, whose web build is
compiled into it), so nothing is downloaded at run time. Nothing here blocks without a bound:

* no display: :func:`open_desktop` says so at once instead of starting a viewer that would hang;
* the desktop viewer is started detached and checked for a quick failure for at most
  :data:`DESKTOP_CHECK_S` seconds;
* the web server is a child process in its own session: :func:`serve_web` waits at most
  ``ready_timeout`` s for its ports and always stops it (SIGTERM, then SIGKILL) on the way out,
  Ctrl-C included.

Ports: the page is served on ``port`` and the recording on ``port + 1`` (Rerun's gRPC proxy,
which the page's ``?url=`` points at), both bound to 127.0.0.1 only.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

from ..errors import SwarmError, UserError

HOST = "127.0.0.1"
DEFAULT_PORT = 9090  # Rerun's own default web-viewer port
DESKTOP_CHECK_S = 3.0  # a desktop viewer still alive after this long is left running
READY_TIMEOUT_S = 30.0  # the web server's ports must answer within this
STOP_TIMEOUT_S = 5.0  # SIGTERM, then SIGKILL after this


class ViewerError(SwarmError):
    """The viewer could not be found or started (exit status 1)."""

    exit_code = 1


def find_rerun() -> Path:
    """The ``rerun`` viewer executable of the running interpreter's environment.

    Looked up without PATH (the venv need not be activated): the binary bundled in the
    ``rerun_cli`` package (one process, so stopping it stops the viewer), else the ``rerun``
    script beside ``sys.executable``, else ``rerun`` on PATH.
    """
    candidates: list[Path] = []
    with contextlib.suppress(ImportError):
        import rerun_cli  # type: ignore[import-untyped]  # the package ships no py.typed marker

        exe = "rerun.exe" if sys.platform.startswith("win") else "rerun"
        candidates.append(Path(rerun_cli.__file__).with_name(exe))
    candidates.append(Path(sys.executable).with_name("rerun"))
    on_path = shutil.which("rerun")
    if on_path:
        candidates.append(Path(on_path))
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    raise ViewerError(
        "the Rerun viewer was not found (it comes with rerun-sdk: pip install rerun-sdk); "
        f"looked for {', '.join(str(c) for c in candidates)}"
    )


def has_display() -> bool:
    """Whether a desktop window can be opened: always on macOS/Windows; on Linux/BSD only with
    ``DISPLAY`` (X11) or ``WAYLAND_DISPLAY`` set."""
    if sys.platform.startswith(("win", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_recording(path: str | Path) -> Path:
    """The recording path, refused with a :class:`UserError` (exit 2) when it cannot be read."""
    p = Path(path)
    if not p.exists():
        raise UserError(f"no such recording: {p}")
    if p.is_dir():
        raise UserError(f"{p} is a directory, not a recording (.rrd)")
    try:
        with p.open("rb") as f:
            f.read(4)
    except OSError as exc:
        raise UserError(f"cannot read {p}: {exc.strerror or exc}") from None
    return p


def check_port(port: int) -> None:
    """Refuse (exit 2) a port out of range or already in use, for the page (``port``) and the
    recording (``port + 1``), before anything starts."""
    if not 1 <= port <= 65534:
        raise UserError(f"--port must be in 1..65534 (the recording is served on port + 1), got {port}")
    for p, what in ((port, "the web page"), (port + 1, "the recording (--port + 1)")):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            # SO_REUSEADDR: a port in TIME_WAIT is free; one with a listener is not (Linux, macOS)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((HOST, p))
            except OSError as exc:
                why = "is in use" if exc.errno == errno.EADDRINUSE else f"cannot be used ({exc.strerror})"
                raise UserError(f"port {p} for {what} {why}; pick another with --port") from None


def web_url(port: int) -> str:
    """The page's address, with the recording's gRPC URL (``port + 1``) in its query."""
    return f"http://{HOST}:{port}/?url=" + quote(f"rerun+http://{HOST}:{port + 1}/proxy", safe="")


def ssh_hint(port: int) -> str:
    """How to reach the served page from another machine."""
    return (
        f"from another machine: ssh -N -L {port}:{HOST}:{port} -L {port + 1}:{HOST}:{port + 1} "
        f"USER@THIS_HOST, then open the same URL there"
    )


def _port_open(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(0.5)
        return s.connect_ex((HOST, port)) == 0


def _tail(f, n: int = 1) -> str:
    """The last ``n`` non-empty lines a child wrote into the temporary file ``f``, ANSI codes removed."""
    import re

    f.flush()
    f.seek(0)
    text = f.read().decode("utf-8", "replace")
    lines = [re.sub(r"\x1b\[[0-9;]*m", "", ln).strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    return " | ".join(lines[-n:]) if lines else "(no output)"


def _stop(proc: subprocess.Popen) -> None:
    """Stop a child started in its own session, and everything it started: SIGTERM to its
    process group, SIGKILL after :data:`STOP_TIMEOUT_S`. Ctrl-C is ignored meanwhile so that a
    second one cannot leave the child behind."""
    if proc.poll() is not None:
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if _main_thread() else None
    try:
        _signal_group(proc, signal.SIGTERM)
        try:
            proc.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            _signal_group(proc, signal.SIGKILL)
            proc.wait(timeout=STOP_TIMEOUT_S)
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def _signal_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        if hasattr(os, "killpg"):
            os.killpg(proc.pid, sig)
        else:  # Windows: no process groups
            proc.kill() if sig == getattr(signal, "SIGKILL", None) else proc.terminate()
    except ProcessLookupError:
        pass


def _popen(cmd: list[str], log) -> subprocess.Popen:
    kw: dict = {"stdin": subprocess.DEVNULL, "stdout": log, "stderr": subprocess.STDOUT}
    if os.name == "posix":
        kw["start_new_session"] = True  # Ctrl-C reaches us, and we stop the whole group
    return subprocess.Popen(cmd, **kw)


@contextlib.contextmanager
def serve_web(
    path: str | Path, port: int = DEFAULT_PORT, *, ready_timeout: float = READY_TIMEOUT_S
) -> Iterator[subprocess.Popen]:
    """Serve ``path`` in Rerun's web viewer on ``127.0.0.1:port`` (recording on ``port + 1``).

    Yields the server process once both ports answer; stops it on exit, whatever happens.
    Raises :class:`UserError` (exit 2) for an unreadable file or a busy port (checked before
    starting), :class:`ViewerError` (exit 1) when the server dies or is not ready in time.
    """
    path = check_recording(path)
    check_port(port)
    cmd = [
        str(find_rerun()),
        "--serve-web",
        "--bind",
        HOST,
        "--web-viewer-port",
        str(port),
        "--port",
        str(port + 1),
        str(path),
    ]
    with tempfile.TemporaryFile() as log:
        proc = _popen(cmd, log)
        try:
            deadline = time.monotonic() + ready_timeout
            while not (_port_open(port) and _port_open(port + 1)):
                if proc.poll() is not None:
                    raise ViewerError(f"the Rerun web viewer stopped (exit {proc.returncode}): {_tail(log)}")
                if time.monotonic() > deadline:
                    raise ViewerError(
                        f"the Rerun web viewer did not answer on ports {port} and {port + 1} "
                        f"within {ready_timeout:.0f} s: {_tail(log)}"
                    )
                time.sleep(0.1)
            yield proc
            if proc.poll() is not None:
                raise ViewerError(f"the Rerun web viewer stopped (exit {proc.returncode}): {_tail(log)}")
        finally:
            _stop(proc)


def serve_until_interrupted(path: str | Path, port: int = DEFAULT_PORT) -> int:
    """``--web``: serve ``path``, print the URL and the SSH hint, and wait for Ctrl-C.

    Ctrl-C (or SIGTERM) stops the server; the exit status is then 130 (printed as one line by
    the CLI). A server that dies by itself is an error (exit 1).
    """
    old_term = None
    if _main_thread() and hasattr(signal, "SIGTERM"):

        def _on_term(signum, frame):
            raise KeyboardInterrupt

        old_term = signal.signal(signal.SIGTERM, _on_term)
    try:
        with serve_web(path, port) as proc:
            print(f"serving {path} in Rerun's web viewer; open: {web_url(port)}", flush=True)
            print(f"  {ssh_hint(port)}; Ctrl-C stops the server", flush=True)
            proc.wait()
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    return 1  # not reached unless the server stopped by itself (serve_web raised then)


def no_display_line(path: str | Path) -> str:
    """One line: why no window opens, and how to view ``path`` instead."""
    return (
        f"no display here (DISPLAY and WAYLAND_DISPLAY unset); view {path} in a browser with: "
        f"swarm-mj view {path} --web   (or on a machine with a screen: rerun {path})"
    )


def open_desktop(path: str | Path) -> int:
    """Open ``path`` in the desktop viewer, detached; return its pid.

    Raises :class:`ViewerError` without a display (at once) or when the viewer fails within
    :data:`DESKTOP_CHECK_S` seconds; a viewer still running then is left running.
    """
    path = check_recording(path)
    if not has_display():
        raise ViewerError(no_display_line(path))
    cmd = [str(find_rerun()), str(path)]
    with tempfile.TemporaryFile() as log:
        proc = _popen(cmd, log)
        try:
            proc.wait(timeout=DESKTOP_CHECK_S)
        except subprocess.TimeoutExpired:
            return proc.pid  # running: the window is up, or coming
        except BaseException:
            _stop(proc)
            raise
        if proc.returncode != 0:
            raise ViewerError(f"the Rerun viewer failed (exit {proc.returncode}): {_tail(log)}")
        return proc.pid


def spawn_note(path: str | Path) -> str:
    """``run --spawn``, after the recording is written: open it in the desktop viewer if possible.

    Never raises and never blocks for more than :data:`DESKTOP_CHECK_S` s: returns the one-line
    note to print (the recording is kept whatever happens).
    """
    try:
        pid = open_desktop(path)
    except SwarmError as exc:
        return f"swarm-mj: note: {exc} (the recording is kept)"
    return f"opened {path} in the Rerun viewer (pid {pid})"
