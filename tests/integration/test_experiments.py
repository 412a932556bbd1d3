"""The experiment layer: the one executor (``parallel.map_ordered``), the one progress bar
(``progress.Progress``), and ``swarm-mj stress`` / ``sweep`` flying through them.

What is checked, and against what:

* results come back in item order, equal to the serial ``[fn(x) for x in items]``, whatever the
  number of workers (items of very different cost, so that they complete out of order);
* workers ignore SIGINT (asked of the worker itself: ``signal.getsignal`` run in it);
* Ctrl-C during a sweep: the parent stops its workers and exits 130 with one line, no traceback;
* the progress bar's text for a percentage and for a count, its lines above the bar, quiet modes;
* ``swarm-mj stress`` writes one row per (rule, seed) in case order and a per-rule table that
  agrees with the rows.
"""

from __future__ import annotations

import io
import json
import math
import os
import signal
import subprocess
import sys

import pytest

from swarm_mj.cli import main as cli_main
from swarm_mj.errors import UserError
from swarm_mj.experiments.parallel import Executor, backend_name, map_ordered, resolve_workers
from swarm_mj.output.progress import Progress

# --------------------------------------------------------------------------- the executor


def test_map_ordered_equals_serial_in_item_order():
    items = [3000, 1, 2500, 2, 2000, 3]  # big and small: the small ones finish first
    seen = []
    bar = Progress(len(items), "t", enabled=False)
    out = map_ordered(math.factorial, items, workers=2, progress=bar, on_result=lambda i, r: seen.append(i))
    assert out == [math.factorial(x) for x in items]
    assert sorted(seen) == list(range(len(items))) and bar.done == len(items)
    assert map_ordered(math.factorial, items, workers=1) == out
    assert map_ordered(math.factorial, [], workers=2) == []


def test_workers_ignore_sigint_and_the_parent_does_not():
    before = signal.getsignal(signal.SIGINT)  # the default handler, unless pytest itself runs with it ignored
    assert map_ordered(signal.getsignal, [signal.SIGINT] * 2, workers=2) == [signal.SIG_IGN] * 2
    assert signal.getsignal(signal.SIGINT) is before  # the parent's handler is left as it was


@pytest.mark.skipif(not os.path.exists("/proc/self"), reason="needs /proc/self to name the worker's pid")
def test_executor_keeps_its_workers_across_calls():
    with Executor(2) as ex:  # os.readlink("/proc/self") is the pid of the process that runs it
        pids = {pid for _ in range(4) for pid in ex.map(os.readlink, ["/proc/self"] * 4)}
        assert ex.map(math.factorial, [5, 3]) == [120, 6] and ex.backend == "processes"
    # the same (at most) two workers every call; a pool per call would show at least one new pid per call
    assert 1 <= len(pids) <= 2 and str(os.getpid()) not in pids
    with pytest.raises(RuntimeError, match="closed"):
        ex.map(math.factorial, [1])


def test_worker_count_checks():
    with pytest.raises(UserError, match="--workers must be >= 1"):
        resolve_workers(0)
    assert resolve_workers(8, 3) == 3 and resolve_workers(None) >= 1
    assert backend_name(1, None) == "in-process" and backend_name(2, None) == "processes"
    assert backend_name(2, "auto") == "ray"


def test_ctrl_c_during_a_sweep_exits_130_in_one_line(tmp_path):
    env = dict(os.environ)
    p = subprocess.Popen(
        [sys.executable, "-m", "swarm_mj.cli", "sweep", "circle", "--seeds", "8", "--duration", "2", "--workers", "2"],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # not ignored, even from a background job
    )
    try:
        first = p.stderr.readline()  # a run has completed: the workers are busy with the next ones
        assert first.startswith("[1/8]"), first
        os.killpg(p.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole process group
        _, err = p.communicate(timeout=600)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130, err
    assert "Traceback" not in err, err
    assert err.strip().splitlines()[-1] == "swarm-mj: interrupted", err


# --------------------------------------------------------------------------- the progress bar


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_percentage_text():
    s = _Tty()
    bar = Progress(200, "circle", stream=s)  # a terminal: enabled
    for k in range(201):
        bar.update(k)
    bar.close()
    frames = s.getvalue().split("\r")[1:]
    assert len(frames) == 101  # one redraw per percent
    assert frames[50].startswith("circle [############-------------]  50%")
    assert frames[-1].startswith("circle [#########################] 100%") and frames[-1].endswith("s\033[K\n")


def test_progress_count_note_and_log():
    s = _Tty()
    bar = Progress(4, "video x.mp4", unit="frames", stream=s)
    bar.note("opening the renderer")
    assert "0/4 frames" in s.getvalue() and s.getvalue().endswith("opening the renderer\033[K")
    bar.advance()  # progress ends the wait: the note goes
    last = s.getvalue().split("\r")[-1]
    assert last.startswith("video x.mp4 [######-------------------] 1/4 frames") and "opening" not in last
    for _ in range(3):
        bar.advance()
    bar.log("done: x.mp4")
    bar.close()
    text = s.getvalue()
    assert "4/4 frames" in text and "frames/s" in text
    assert "\r\033[Kdone: x.mp4\n" in text  # the line is printed above the bar, which is redrawn


def test_progress_quiet_when_not_a_terminal_but_lines_still_print():
    s = io.StringIO()  # not a terminal
    bar = Progress(3, "sweep", stream=s)
    bar.update(2)
    bar.log("[1/3] a run")
    bar.close()
    assert s.getvalue() == "[1/3] a run\n"
    s = io.StringIO()
    bar = Progress(3, "sweep", enabled=False, stream=s)  # --quiet
    bar.update(2)
    bar.log("[1/3] a run")
    bar.close()
    assert s.getvalue() == ""


# --------------------------------------------------------------------------- stress


def test_stress_rows_in_case_order_and_table_from_rows(tmp_path, capsys):
    out = tmp_path / "s.json"
    rc = cli_main(
        [
            "stress",
            "--starts",
            "2",
            "--followers",
            "2",
            "--duration",
            "1",
            "--workers",
            "2",
            "--quiet",
            "--json",
            str(out),
        ]
    )
    assert rc == 0
    data = json.loads(out.read_text())
    rows = data["starts"]
    assert [(r["rule"], r["seed"]) for r in rows] == [("layers", 0), ("layers", 1), ("paper", 0), ("paper", 1)]
    for rule in ("layers", "paper"):
        mine = [r for r in rows if r["rule"] == rule]
        t = data["table"][rule]
        assert t["starts"] == 2 and t["contacts"] == sum(r["contacts"] for r in mine)
        assert t["starts_with_contact"] == sum(r["contacts"] > 0 for r in mine)
    printed = capsys.readouterr().out
    assert printed.splitlines()[0].startswith("rule") and "(2 followers)" in printed
