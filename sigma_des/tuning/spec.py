"""The ``[tune]`` settings and the genes: which aircraft parameters the GA adjusts.

A gene is one float field of :class:`~sigma_des.agents.params.AircraftParams`
(rigid body, rotor, actuator: the paper's structural and actuator parameters
phi_act) or of its :class:`~sigma_des.agents.params.AeroCoeffs` (the paper's
aerodynamic coefficients phi_c); aerodynamic names are unambiguous, so both are
given by their bare field name (``ixx``, ``rotor_pitch``, ``cm_a``). The
rotor's C_T and C_Q of eq. (7) are set through ``rotor_pitch`` (thrust) and
``rotor_cd0`` (profile torque) of the blade-element model (rotor.py).

The paper gives no population, generations, selection, mutation or bounds;
ours are below (all configurable, all seeded). The defaults leave out what
the paper measures rather than tunes (mass and, for the fixed wing, inertia:
the "structural parameters" of its Fig. 5): an airframe's angular response
depends on moment coefficient / inertia only, so tuning both is ill-posed.
Bounds default to
``[scale_low, scale_high]`` times the starting value (``x [0.5, 2]``, the
paper-notes' default for CFD-derived values; reversed for a negative value).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from sigma_des.agents.fitted import PARAM_NAMES, get_value, with_values
from sigma_des.agents.params import AeroCoeffs, AircraftParams, check_range
from sigma_des.errors import ConfigError

#: the aerodynamic coefficients' names (their range keys are ``aero.<name>``)
_AERO = tuple(f.name for f in fields(AeroCoeffs))

__all__ = ["TuneSpec", "GENE_NAMES", "DEFAULT_GENES", "DEFAULT_CHANNELS", "get_value",
           "with_values", "bounds"]

#: Every parameter name a gene may be (those of :mod:`sigma_des.agents.fitted`).
GENE_NAMES: tuple[str, ...] = PARAM_NAMES
#: Genes tuned when ``tune.params`` is empty.
DEFAULT_GENES: dict[str, tuple[str, ...]] = {
    "quadrotor": ("ixx", "iyy", "izz", "rotor_pitch", "rotor_cd0", "tau_motor", "cd_0"),
    "fixedwing": ("cm_a", "cm_q", "cm_de", "cll_p", "cll_da", "cl_a", "cd_0"),
}

#: DTW point columns when ``tune.channels`` is empty. Raw SI units, so for a
#: 20 m/s fixed wing position errors (m) would swamp the attitude (rad): it is
#: fitted on attitude and rates only (the paper fits it on rates).
DEFAULT_CHANNELS: dict[str, tuple[str, ...]] = {
    "quadrotor": ("phi", "theta", "psi", "p", "q", "r", "x", "y", "h"),
    "fixedwing": ("phi", "theta", "p", "q", "r"),
}


#: Largest population: a generation of 10000 on a 3 s, 100 Hz log is a batched flight
#: estimated at 0.7 GiB, about a minute (population 5000 measured 0.5 GB peak RSS and
#: 33 s on a loaded machine; 100000 grew for minutes into gigabytes). Longer logs are
#: bounded further by the memory estimate (``--force`` skips it).
MAX_POPULATION = 10_000


@dataclass(frozen=True)
class TuneSpec:
    """GA and fitness settings (TOML table ``[tune]``; ``--set tune.<key>=...``).

    Attributes:
        seed: root seed of the GA's random stream (``tuning.ga``).
        population: individuals per generation (P; one batched flight of P aircraft),
            at most :data:`MAX_POPULATION`.
        generations: generations after the initial one.
        tournament: tournament size of the selection.
        cxpb: probability that a pair is recombined by arithmetic crossover (eq. 12).
        mutpb: probability that an individual is mutated.
        sigma: Gaussian mutation std in generation 1, as a fraction of each gene's
            bound width; multiplied by ``sigma_decay`` every generation (coarse
            search first, refinement later), floored at ``sigma_min``.
        sigma_decay: per-generation factor of the mutation std.
        sigma_min: smallest mutation std (fraction of the bound width).
        indpb: per-gene mutation probability of a mutated individual.
        elite: best individuals copied unchanged into the next generation.
        rate: resampling rate of the logs (Hz): the DTW sum grows with sample count,
            so a fixed rate makes fitness values comparable across logs.
        segment: replay window (s); every window restarts from the logged state
            (multiple shooting), so an open-loop-unstable airframe stays near the log.
        params: gene names (empty = :data:`DEFAULT_GENES` of the aircraft kind).
        lower, upper: absolute bounds per gene (empty = scale bounds).
        scale_low, scale_high: relative bounds around the starting value.
        channels: logged state columns that form a DTW point (flightlog.STATE_COLUMNS;
            empty = :data:`DEFAULT_CHANNELS` of the aircraft kind).
        band: Sakoe–Chiba band of the DTW in samples (-1 = unconstrained). Unconstrained
            DTW forgives a time-scale error, i.e. dynamics uniformly too fast or too
            slow (moment coefficients all scaled), which is exactly what tuning must
            see; the default band of 3 samples (60 ms at 50 Hz) tolerates timestamp
            jitter and little more.
    """

    seed: int = 1
    population: int = 32
    generations: int = 30
    tournament: int = 3
    cxpb: float = 0.7
    mutpb: float = 0.3
    sigma: float = 0.1
    sigma_decay: float = 0.97
    sigma_min: float = 0.002
    indpb: float = 0.5
    elite: int = 2
    rate: float = 50.0
    segment: float = 1.0
    params: tuple[str, ...] = ()
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()
    scale_low: float = 0.5
    scale_high: float = 2.0
    channels: tuple[str, ...] = ()
    band: int = 3

    def __post_init__(self) -> None:
        from sigma_des.tuning.flightlog import STATE_COLUMNS

        def req(ok: bool, key: str, why: str) -> None:
            if not ok:
                raise ConfigError(f"tune.{key}", why)

        req(0 <= self.seed < 2**63, "seed", f"must be in 0..2^63-1, got {self.seed}")
        req(2 <= self.population <= MAX_POPULATION, "population",
            f"must be in 2..{MAX_POPULATION}, got {self.population}")
        req(0 <= self.generations <= 100_000, "generations",
            f"must be in 0..100000, got {self.generations}")
        req(1 <= self.tournament <= self.population, "tournament",
            f"must be in 1..population ({self.population}), got {self.tournament}")
        for k in ("cxpb", "mutpb", "indpb"):
            v = getattr(self, k)
            req(0.0 <= v <= 1.0, k, f"must be in [0, 1], got {v}")
        req(0.0 < self.sigma <= 1.0, "sigma", f"must be in (0, 1], got {self.sigma}")
        req(0.0 < self.sigma_decay <= 1.0, "sigma_decay",
            f"must be in (0, 1], got {self.sigma_decay}")
        req(0.0 < self.sigma_min <= self.sigma, "sigma_min",
            f"must be in (0, sigma={self.sigma}], got {self.sigma_min}")
        req(0 <= self.elite < self.population, "elite",
            f"must be in 0..population-1 ({self.population - 1}), got {self.elite}")
        req(0.0 < self.rate <= 1000.0, "rate", f"must be in (0, 1000] Hz, got {self.rate}")
        req(0.0 < self.segment <= 3600.0, "segment",
            f"must be in (0, 3600] s, got {self.segment}")
        for i, g in enumerate(self.params):
            req(g in GENE_NAMES, f"params[{i}]",
                f"unknown parameter {g!r}; allowed: {', '.join(GENE_NAMES)}")
        req(len(set(self.params)) == len(self.params), "params", "names a parameter twice")
        for k in ("lower", "upper"):
            v = getattr(self, k)
            req(len(v) in (0, len(self.params)) and (len(v) == 0 or bool(self.params)), k,
                f"must be empty or hold one value per tune.params entry "
                f"({len(self.params)}), got {len(v)}")
            req(all(math.isfinite(x) for x in v), k, "must be finite")
        req(len(self.lower) == len(self.upper), "upper",
            "tune.lower and tune.upper must both be given or both be empty")
        for i, (lo, hi) in enumerate(zip(self.lower, self.upper, strict=True)):
            req(lo <= hi, f"lower[{i}]",
                f"lower bound {lo} > upper bound {hi} for {self.params[i]!r}")
        req(0.0 < self.scale_low <= 1.0 <= self.scale_high, "scale_low",
            f"need 0 < scale_low <= 1 <= scale_high, got {self.scale_low}, {self.scale_high}")
        req(-1 <= self.band <= 100_000, "band", f"must be -1 (none) or >= 0, got {self.band}")
        for i, c in enumerate(self.channels):
            req(c in STATE_COLUMNS, f"channels[{i}]",
                f"unknown column {c!r}; allowed: {', '.join(STATE_COLUMNS)}")

    def genes(self, kind: str) -> tuple[str, ...]:
        """The gene names for aircraft ``kind``."""
        return self.params or DEFAULT_GENES[kind]

    def channels_of(self, kind: str) -> tuple[str, ...]:
        """The DTW point columns for aircraft ``kind``."""
        return self.channels or DEFAULT_CHANNELS[kind]


def _check_bounds(spec: TuneSpec, i: int, gene: str, lo: float, hi: float) -> None:
    """Both bounds of gene ``i`` inside the aircraft's plausible range (PARAM_RANGES):
    the GA must never fly a candidate that the model refuses mid-run."""
    name = f"aero.{gene}" if gene in _AERO else gene
    for end, v in (("lower", lo), ("upper", hi)):
        why = check_range(name, v)
        if why:
            key = f"tune.{end}[{i}]" if spec.lower else (
                "tune.scale_low" if end == "lower" else "tune.scale_high")
            raise ConfigError(key, f"{end} bound of {gene!r} {why}")


def bounds(spec: TuneSpec, start: AircraftParams, kind: str
           ) -> tuple[tuple[str, ...], list[float], list[float]]:
    """Gene names and their lower / upper bounds for a GA started at ``start``."""
    names = spec.genes(kind)
    if spec.lower:
        lo, hi = list(spec.lower), list(spec.upper)
    else:
        lo, hi = [], []
        for g in names:
            v = get_value(start, g)
            a, b = v * spec.scale_low, v * spec.scale_high
            lo.append(min(a, b))
            hi.append(max(a, b))
    for i, g in enumerate(names):
        _check_bounds(spec, i, g, lo[i], hi[i])
        v = get_value(start, g)
        if not lo[i] <= v <= hi[i]:
            raise ConfigError(f"tune.lower[{i}]", f"bounds [{lo[i]}, {hi[i]}] of {g!r} do not "
                              f"contain its starting value {v}")
        if lo[i] == hi[i]:
            raise ConfigError(f"tune.params[{i}]", f"{g!r} has zero-width bounds (starting "
                              f"value {v}); give tune.lower/tune.upper or drop it")
    return names, lo, hi
