"""The lab: sigma_des's research code, kept out of the ``sigma-des`` wheel.

:mod:`sigma_lab.studies` is what the paper studies, the benchmarks and the live
validation suite in ``experiments/`` share; :mod:`sigma_lab.reference` holds the
independent process-per-message SimPy model the engine benchmark times against.
It is installed in the development set-up only (``pip install -e ./lab``) and imports
the product (``sigma_des``); the product never imports it.
"""
