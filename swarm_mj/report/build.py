"""``build_report``: plan the jobs, run them, assemble the numbers, draw the figures, write the files."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from ..errors import UserError
from ..experiments.parallel import resolve_workers
from ..output.progress import Progress, say
from .assemble import assemble, jsonable
from .figures import draw_all, draw_snapshot
from .jobs import run_jobs
from .plan import ALL_FIGURES, Plan, load_fpa_gains, plan_jobs
from .tables import render_markdown

SNAPSHOT_KEY = "snapshot/scenario1"


def build_report(
    out_dir: str | Path = "report",
    *,
    plan: Plan | None = None,
    quick: bool = False,
    workers: int | None = None,
    progress: bool = False,
) -> dict:
    """Run every experiment, write ``out_dir``/README.md, results.json and the PNGs; return the results.

    ``progress``: one line per completed job on stderr, under a progress bar when it is a terminal.
    """
    plan = plan or (Plan.quick() if quick else Plan.full())
    w = resolve_workers(workers)
    out = _prepare_output(Path(out_dir))
    tell = say if progress else (lambda line: None)
    t_start = time.perf_counter()

    fpa = load_fpa_gains()
    jl = plan_jobs(plan, fpa)
    total = len(jl.jobs)
    used = min(w, total)
    tell(f"report ({plan.name}): {total} jobs on {used} worker(s)")
    bar = Progress(total, f"report ({plan.name})", None if progress else False, unit="jobs")
    try:
        res = run_jobs(jl.jobs, jl.sweeps, used, bar=bar, say=bar.log if progress else None)
    finally:
        bar.close()

    R = assemble(plan, fpa, jl, res, used)
    tell("drawing figures")
    R["figures"] = _draw_figures(out, R, res.by_key, plan, tell)
    R["meta"]["wall_s"] = time.perf_counter() - t_start
    R["meta"]["jobs_wall_s"] = res.wall_s
    R["meta"]["cpu_s_in_runs"] = float(sum(r.get("wall_s", 0.0) for r in res.by_index if isinstance(r, dict)))

    data = _write(out, R)
    tell(
        f"wrote {out / 'README.md'}, {out / 'results.json'} and {len(R['figures'])} figure(s) in "
        f"{R['meta']['wall_s']:.0f} s"
    )
    return data


def _prepare_output(out: Path) -> Path:
    """The output folder, made; one clear UserError when it cannot be, or when matplotlib is missing."""
    if out.exists() and not out.is_dir():
        raise UserError("exists and is not a folder", where=str(out))
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise UserError("the report draws its figures with matplotlib: pip install 'swarm-mj[report]'") from None
    out.mkdir(parents=True, exist_ok=True)
    return out


def _draw_figures(out: Path, R: dict, by_key: dict[str, Any], plan: Plan, tell) -> list[dict]:
    """Every figure, then the MuJoCo still; a stale figure of an earlier report is removed."""
    logs = {k: v["log"] for k, v in by_key.items() if isinstance(v, dict) and "log" in v and k != SNAPSHOT_KEY}
    figures = draw_all(out, R, logs)
    if plan.snapshot and SNAPSHOT_KEY in by_key:
        figures += draw_snapshot(out, by_key[SNAPSHOT_KEY]["log"], tell)
    made = {f["file"] for f in figures}
    for name in ALL_FIGURES - made:
        (out / name).unlink(missing_ok=True)
    return figures


def _write(out: Path, R: dict) -> dict:
    """results.json (strict JSON) and README.md, each written atomically; returns the JSON data."""
    from ..output.atomic import write_json_atomic

    data = jsonable(R)
    write_json_atomic(out / "results.json", data)
    tmp = out / "README.md.partial"
    tmp.write_text(render_markdown(data))
    os.replace(tmp, out / "README.md")
    return data
