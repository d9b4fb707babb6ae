"""Live vs DES validation (the suite): calibrate on one live run, predict the rest.

* :mod:`~sigma_lab.studies.validation.grid` — the cells (N, hosts, message mode,
  impairment, repeats of the calibration setting) and the wall-time estimate;
* :mod:`~sigma_lab.studies.validation.scoring` — errors, the live noise floor, the
  bands and the knee (pure; hand-tested);
* :mod:`~sigma_lab.studies.validation.runs` — bounded live runs, the calibration,
  the DES predictions;
* :mod:`~sigma_lab.studies.validation.suite` — the plan run resumably;
* :mod:`~sigma_lab.studies.validation.report` — ``cells.csv``, ``summary.md``, the plot;
* :mod:`~sigma_lab.studies.validation.coverage` — the intervals' coverage on the
  held-out cells and the ``residuals.toml`` ``sigma-des predict`` reads;
  :mod:`~sigma_lab.studies.validation.kneeplot` — ``knee.png``;
* :mod:`~sigma_lab.studies.validation.loaded` — a calibration made under a CPU hog
  against an idle one (``--loaded-check``);
* :mod:`~sigma_lab.studies.validation.stages` — the state latency split by stage and
  publish order, live against the DES, per cell (``python -m``; not part of the suite).

``experiments/live_vs_des.py`` is the command line; lab/record/LIVE.md (*Validation*) says
how to read the outputs.
"""

from sigma_lab.studies.validation.grid import Cell, Plan, full_plan, hosts_for, quick_plan
from sigma_lab.studies.validation.report import write_outputs
from sigma_lab.studies.validation.suite import run_suite

__all__ = ["Cell", "Plan", "full_plan", "hosts_for", "quick_plan", "run_suite", "write_outputs"]
