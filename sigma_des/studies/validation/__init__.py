"""Live vs DES validation (issue 24, item 6): calibrate on one live run, predict the rest.

* :mod:`~sigma_des.studies.validation.grid` — the cells (N, hosts, message mode,
  impairment, repeats of the calibration setting) and the wall-time estimate;
* :mod:`~sigma_des.studies.validation.scoring` — errors, the live noise floor, the
  bands and the knee (pure; hand-tested);
* :mod:`~sigma_des.studies.validation.runs` — bounded live runs, the calibration,
  the DES predictions;
* :mod:`~sigma_des.studies.validation.suite` — the plan run resumably;
* :mod:`~sigma_des.studies.validation.report` — ``cells.csv``, ``summary.md``, the plot.

``experiments/live_vs_des.py`` is the command line; docs/LIVE.md (*Validation*) says
how to read the outputs.
"""

from sigma_des.studies.validation.grid import Cell, Plan, full_plan, hosts_for, quick_plan
from sigma_des.studies.validation.report import write_outputs
from sigma_des.studies.validation.suite import run_suite

__all__ = ["Cell", "Plan", "full_plan", "hosts_for", "quick_plan", "run_suite", "write_outputs"]
