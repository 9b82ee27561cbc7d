"""Voter hazard rate (seed 002 sections 4.6-4.7, seed 004 section on THR derivation).

One 2oo2 obstacle-detection (OD) module is modelled as the CTMC of seed 002's Listing 5:
an environment generates a demand d (1 = obstacle present, 2 = degraded input), two
independent channels (c = conventional, n = neural network) each sense, perceive and
communicate, and a voter synchronises with both and produces (r, f): the voting result and
the failure flag. P[FN] is the probability of eventually reaching a `fin` state (stage 5,
flag muted, and either contradictory channel results or a wrong result), computed here
exactly by a linear solve on the embedded jump chain, and cross-checked with Storm on an
independently written PRISM program (exact rationals and the parametric rational function
P[FN](p_n, p_c) that seed 002 plots in Fig. 6a). The fused 3oo3 system's hazard rate is
seed 002 eq. (5): HR = lambda_od * P[FN]^3 (Fig. 6b). The targets it is compared with:
1e-7 /h (SIL 3, seed 002 eq. (1)), 1e-9 /h (CSM-DT "catastrophic", seed 004) and the
SNCF open-data estimate recomputed from seed 004's table.

The pieces, one concept each: `numbers` (the paper's figures and the targets), `ctmc` (the
module's chain), `solve` (P[FN] and the hazard rate), `storm` (the PRISM program and Storm),
`sncf` (seed 004's estimate), `figures`, `part` (`section`) and `markdown` (the section's
text). This package re-exports their public names, so `from verification import hazard`
(and `from verification.hazard import THR_SIL3`) reads as before.
"""
from __future__ import annotations

from .numbers import (
    EN50129_MODULE_RATE, HR_REL_TOL, LAMBDA_OD, PAPER_HR, PAPER_MODULE_HR, PAPER_P, PAPER_PFN, PAPER_PFN_RANGE,
    PFN_REL_TOL, P_RANGE, STORM_TOL, THR_CATASTROPHIC, THR_SIL3,
)
from .ctmc import (
    ACTIONS, CHANNELS, COMC, COMN, D, F, INIT, PERC, PERN, R, SC, SENC, SENN, SN, Chain, ModuleParams, build_chain,
)
from .solve import eq4, grid_values, hazard_rate, p_fn, p_fn_grid, p_fn_many, reach_fin
from .storm import Storm, prism_program
from .sncf import SNCF_COLLISIONS, SNCF_ESR, SNCF_HOURS_PER_DAY, SNCF_PAPER, SNCF_TRAINS, SNCF_YEARS, sncf
from .part import section

__all__ = [
    "EN50129_MODULE_RATE", "HR_REL_TOL", "LAMBDA_OD", "PAPER_HR", "PAPER_MODULE_HR", "PAPER_P", "PAPER_PFN",
    "PAPER_PFN_RANGE", "PFN_REL_TOL", "P_RANGE", "STORM_TOL", "THR_CATASTROPHIC", "THR_SIL3", "ACTIONS", "CHANNELS",
    "COMC", "COMN", "D", "F", "INIT", "PERC", "PERN", "R", "SC", "SENC", "SENN", "SN", "Chain", "ModuleParams",
    "build_chain", "eq4", "grid_values", "hazard_rate", "p_fn", "p_fn_grid", "p_fn_many", "reach_fin", "Storm",
    "prism_program", "SNCF_COLLISIONS", "SNCF_ESR", "SNCF_HOURS_PER_DAY", "SNCF_PAPER", "SNCF_TRAINS", "SNCF_YEARS",
    "sncf", "section",
]
