"""``swarm-mj report``: the paper's experiments, ours beside the paper's, as Markdown + PNG + JSON.

:func:`build_report` flies every experiment of the paper (and the checks of
docs/interpretations.md §4 and §7) as independent jobs through the one executor
(:func:`swarm_mj.experiments.parallel.map_ordered`), longest first, then draws the figures (matplotlib, Agg)
and writes

* ``results.json`` — every number (the README tables are generated from it, and so is the
  report's README by :func:`render_markdown`, so the two cannot disagree);
* ``README.md`` — each paper figure or table beside ours, with the difference, and the
  interpretations of docs/interpretations.md;
* ``*.png`` — the figures (step response like Fig. 7/8, tracking like Fig. 9, swarm paths
  like Figs. 10–13, distances like Fig. 14, wind like Fig. 15, anti-collision like Fig. 16b,
  wind robustness over seeds, FPA convergence).

A :class:`Plan` fixes the durations and seed counts: :meth:`Plan.full` is the paper's
(180 s runs, 20 seeds), :meth:`Plan.quick` a few-seconds-per-run version for development.
Each run depends only on its scenario and seed, so the numbers do not depend on the
number of workers.

The rooms: :mod:`.plan` (the Plan and the job list), :mod:`.jobs` (worker side, and running
them), :mod:`.assemble` (results.json, section by section), :mod:`.tables` (the Markdown),
:mod:`.figures` (the ten figures and the MuJoCo still), :mod:`.build` (the whole, in order).
"""

from __future__ import annotations

from .assemble import INTERPRETATIONS, assemble, jsonable
from .build import build_report
from .figures import draw_all, draw_snapshot
from .jobs import IseJob, JobResults, RunJob, TuneJob, do_job, run_jobs
from .plan import (
    ALL_FIGURES,
    GAINS_FILE,
    PAPER_STEP_MAX_ANGLE_DEG,
    PAPER_TABLE3,
    FpaGains,
    JobList,
    Plan,
    load_fpa_gains,
    plan_jobs,
    random_crossing,
)
from .tables import load_results, render_markdown

__all__ = [
    "ALL_FIGURES",
    "GAINS_FILE",
    "INTERPRETATIONS",
    "PAPER_STEP_MAX_ANGLE_DEG",
    "PAPER_TABLE3",
    "FpaGains",
    "IseJob",
    "JobList",
    "JobResults",
    "Plan",
    "RunJob",
    "TuneJob",
    "assemble",
    "build_report",
    "do_job",
    "draw_all",
    "draw_snapshot",
    "jsonable",
    "load_fpa_gains",
    "load_results",
    "plan_jobs",
    "random_crossing",
    "render_markdown",
    "run_jobs",
]
