"""The numbers the hazard part is measured against: seed 002's P[FN], hazard rates and
parameter range, the demand rate lambda_od, the tolerable hazard rates (SIL 3, CSM-DT
catastrophic; `verification.stress` compares with them too) and the tolerances.
"""
from __future__ import annotations

from fractions import Fraction


PAPER_P = 0.04                 # seed 002: p_f^n = p_f^c = 0.04
PAPER_PFN = 0.0016             # seed 002: P[FN](0.04, 0.04)
PAPER_HR = 3.413e-10           # seed 002 eq. (5) at that point, per hour
PAPER_MODULE_HR = 6e-5         # seed 002 section 4.6: "lambda_od * 0.0016 = 6e-5"
PAPER_PFN_RANGE = (0.0016, 0.005)   # seed 002 section 4.6: range of Fig. 6a
LAMBDA_OD = 2.0 / 24.0         # obstacle or degraded-data occurrences per hour
THR_SIL3 = 1e-7                # seed 002 eq. (1); seed 004 CSM-DT "critical"
THR_CATASTROPHIC = 1e-9        # seed 004 CSM-DT "catastrophic" (highly improbable)
EN50129_MODULE_RATE = 2e-4     # seed 002 section 4.7: premise of EN 50129 B.3.5.2 rule
P_RANGE = (Fraction(1, 50), Fraction(1, 10))   # p_n, p_c in [0.02, 0.1]

PFN_REL_TOL = 0.05             # the paper prints 0.0016 with two significant digits
HR_REL_TOL = (1 + PFN_REL_TOL) ** 3 - 1      # what 5 % on P[FN] becomes after cubing
STORM_TOL = 1e-9
