"""Automatic model tuning (the paper's §IV.A, Fig. 6): fit the 6-DoF model to flight logs.

Modules: flightlog (CSV logs, validation, resampling), spec (``[tune]`` settings,
genes and bounds), replay (logged control signals through the model, one
candidate or a whole population in one batched flight), fitness (eq. 13 with
exact DTW; R² / RMS), ga (DEAP GA with the paper's arithmetic crossover),
synth (logs flown by our own model for the identifiability test).
"""
