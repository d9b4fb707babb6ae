"""Reference models: independent re-implementations of the model contract.

* :mod:`~sigma_lab.reference.process_model` — the textbook one-process-per-message
  SimPy model of a restricted scenario class; the engine benchmark
  (``experiments/bench_engine.py``) times the engine against it and cross-checks
  their metrics.
"""
