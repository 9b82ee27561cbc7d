"""Seed 004's SNCF open-data estimate: obstacle-related remarkable safety events per year,
lambda = N / (H x U), and its 95 % intervals (normal as stated, Student t, exact Poisson).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import stats


# seed 004: SNCF open data, obstacle-related ESRs (remarkable safety events) per year
SNCF_YEARS = (2014, 2015, 2016, 2017)
SNCF_COLLISIONS = (7, 26, 21, 16)
SNCF_ESR = (1, 3, 5, 4)
SNCF_HOURS_PER_DAY = 16
SNCF_TRAINS = 15000
SNCF_PAPER = {"mean": 3.25, "sd": 1.7, "sem": 0.85, "ci_year": (1.8, 5.6),
              "hours": 87_600_000, "ci_hour": (1.8e-8, 5.6e-8)}


def sncf() -> dict:
    """Seed 004: lambda = N / (H x U) from the SNCF open-data ESR counts, 95 % intervals."""
    x = np.array(SNCF_ESR, dtype=float)
    n = len(x)
    mean = float(x.mean())
    sd = float(x.std(ddof=1))
    sem = sd / math.sqrt(n)
    z = float(stats.norm.ppf(0.975))
    hours = SNCF_HOURS_PER_DAY * 365 * SNCF_TRAINS
    ci_normal = (mean - z * sem, mean + z * sem)
    t = float(stats.t.ppf(0.975, n - 1))
    ci_t = (mean - t * sem, mean + t * sem)
    total = int(x.sum())
    ci_poisson = (stats.chi2.ppf(0.025, 2 * total) / 2 / n, stats.chi2.ppf(0.975, 2 * total + 2) / 2 / n)
    return {"mean": mean, "sd": sd, "sem": sem, "z": z, "hours": hours,
            "rate": mean / hours,
            "ci_year_normal": ci_normal, "ci_hour_normal": tuple(v / hours for v in ci_normal),
            "ci_year_t": ci_t, "ci_year_poisson": tuple(float(v) for v in ci_poisson),
            "ci_hour_from_paper_year": tuple(v / hours for v in SNCF_PAPER["ci_year"]),
            "collisions_rate": float(np.mean(SNCF_COLLISIONS)) / hours}
