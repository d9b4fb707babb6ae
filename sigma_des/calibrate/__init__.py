"""Calibration: fit the DES's parameters to a live run (``sigma-des calibrate``).

``fit`` reads the run's message table and writes the calibrated scenario; ``fit_step``
fits the node step time, ``fit_cpu`` the deployment (cores, per-message CPU demands,
run-queue waits) from ``demands``; ``dequeue`` removes queueing from measured
latencies before they become per-hop draws; ``match`` rescales the hops until the DES
re-predicts the run; ``insample`` is that check; ``campaign`` combines several runs;
``cli`` the subcommand.

Predictions from a calibration (``sigma-des predict`` and ``capacity``): ``target``
prepares the calibrated scenario for a target (the one function the validation suite
uses too) and runs the DES's figures; ``intervals`` widens them by the seeds' spread
and the validation's residuals (``residuals.toml``); ``predict`` and ``capacity`` the
two commands' logic, ``predict_cli`` their command line.
"""
