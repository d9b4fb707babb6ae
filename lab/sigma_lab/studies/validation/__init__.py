"""Live vs DES validation (issue 24, item 6): calibrate on one live run, predict the rest.

* :mod:`~sigma_lab.studies.validation.grid` — the cells (N, hosts, message mode,
  impairment, repeats of the calibration setting) and the wall-time estimate;
* :mod:`~sigma_lab.studies.validation.scoring` — errors, the live noise floor, the
  bands and the knee (pure; hand-tested);
* :mod:`~sigma_lab.studies.validation.runs` — bounded live runs, the calibration,
  the DES predictions;
* :mod:`~sigma_lab.studies.validation.suite` — the plan run resumably;
* :mod:`~sigma_lab.studies.validation.report` — ``cells.csv``, ``summary.md``, the plot.

``experiments/live_vs_des.py`` is the command line; lab/record/LIVE.md (*Validation*) says
how to read the outputs.
"""

from sigma_lab.studies.validation.grid import Cell, Plan, full_plan, hosts_for, quick_plan
from sigma_lab.studies.validation.report import write_outputs
from sigma_lab.studies.validation.suite import run_suite

__all__ = ["Cell", "Plan", "full_plan", "hosts_for", "quick_plan", "run_suite", "write_outputs"]
