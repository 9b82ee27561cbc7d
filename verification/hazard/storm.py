"""The independent cross-check: the module written again from Listing 5 as a PRISM program
(`prism_program`, sharing nothing with `ctmc`) and checked by Storm (`Storm`): exact
rationals at chosen points, and the parametric rational function P[FN](p_n, p_c).
"""
from __future__ import annotations

import os
import tempfile
from fractions import Fraction

from .ctmc import ModuleParams


def prism_program(p: ModuleParams, parametric: bool = False) -> str:
    """The module as a PRISM CTMC, written from Listing 5 (independent of _successors)."""
    def num(x: float) -> str:
        fr = Fraction(x).limit_denominator(10 ** 12) if not isinstance(x, Fraction) else x
        if abs(float(fr) - float(x)) > 1e-15:
            fr = Fraction(x)
        return f"{fr.numerator}/{fr.denominator}"

    consts = [("pn", p.p_n), ("pc", p.p_c), ("pv", p.p_v), ("ps", p.p_s), ("pcom", p.p_com), ("q", p.q_obs)]
    lines = ["ctmc", ""]
    for name, v in consts:
        if parametric and name in ("pn", "pc"):
            lines.append(f"const double {name};")
        else:
            lines.append(f"const double {name} = {num(v)};")
    for a, c in (("gen", "lg"), ("sense_c", "lsc"), ("sense_n", "lsn"), ("perc_c", "lpc"), ("perc_n", "lpn"),
                 ("com_c", "lcc"), ("com_n", "lcn"), ("vote", "lv")):
        lines.append(f"const double {c} = {num(p.rate(a))};")
    degraded_perceive = ("(1-pc)*lpc:(perc'=2)&(sc'=3) + pc*lpc:(perc'=0)&(sc'=3)" if p.degraded == "perceptor"
                         else "lpc:(perc'=2)&(sc'=3)")
    uc = "(comc=2 | comn=2 | comc!=comn)"
    agree = "(comc=1 | comc=comn)" + (f" & !{uc}" if p.guards == "disjoint" else "")
    fin = {"paper": "(comc!=comn | (comc=comn & r!=d))", "wrong": "r!=d", "clear": "r=0"}[p.fin]
    lines += [
        "",
        "module Environment",
        "  d : [0..2] init 0;",
        "  [generate] d=0 -> q*lg:(d'=1) + (1-q)*lg:(d'=2);",
        "endmodule",
        "",
        "module ChannelC",
        "  sc : [0..5] init 0;",
        "  senc : [0..2] init 0;",
        "  perc : [0..2] init 0;",
        "  comc : [0..2] init 0;",
        "  [generate] sc=0 -> 1:(sc'=1);",
        "  [] sc=1 & d=1 -> (1-ps)*lsc:(senc'=1)&(sc'=2) + ps*lsc:(senc'=0)&(sc'=2);",
        "  [] sc=1 & d=2 -> (1-ps)*lsc:(senc'=2)&(sc'=2) + ps*lsc:(senc'=0)&(sc'=2);",
        "  [] sc=2 & senc=0 -> lpc:(perc'=0)&(sc'=3);",
        "  [] sc=2 & senc=1 -> (1-pc)*lpc:(perc'=1)&(sc'=3) + pc*lpc:(perc'=0)&(sc'=3);",
        f"  [] sc=2 & senc=2 -> {degraded_perceive};",
        "  [] sc=3 -> (1-pcom)*lcc:(comc'=perc)&(sc'=4) + pcom*lcc:(comc'=0)&(sc'=4);",
        "  [vote] sc=4 -> 1:(sc'=5);",
        "endmodule",
        "",
        "module ChannelN = ChannelC [sc=sn, senc=senn, perc=pern, comc=comn, pc=pn, lsc=lsn, lpc=lpn, lcc=lcn] endmodule",
        "",
        "module Voter",
        "  r : [0..2] init 0;",
        "  f : bool init false;",
        f"  [vote] sc=4 & sn=4 & {uc} -> (1-pv)*lv:(f'=true)&(r'=max(comc,comn))"
        " + pv/3*lv:(f'=false)&(r'=0) + pv/3*lv:(f'=false)&(r'=1) + pv/3*lv:(f'=false)&(r'=2);",
        f"  [vote] sc=4 & sn=4 & {agree} -> (1-pv)*lv:(f'=false)&(r'=comc)"
        " + pv/3*lv:(f'=true) + pv/3*lv:(f'=false)&(r'=0) + pv/3*lv:(f'=false)&(r'=2);",
        "endmodule",
        "",
        f'label "fin" = sc=5 & sn=5 & !f & {fin};',
        "",
    ]
    return "\n".join(lines)


class Storm:
    """Storm (stormpy) on the PRISM text: exact rational results and the parametric P[FN]."""

    def __init__(self):
        import stormpy  # noqa: F401  (raises ImportError if missing)
        import stormpy.developer as dev
        self.stormpy = stormpy
        self.dev = dev
        self.version = getattr(stormpy, "__version__", "?")

    def _program(self, text: str):
        sp_ = self.stormpy
        fd, path = tempfile.mkstemp(suffix=".prism", prefix="od2oo2_")
        try:
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
            # PRISM semantics for synchronised rates (product) needs the compatibility mode;
            # Storm warns about that on every build, which is expected here.
            old = self.dev.get_log_level()
            self.dev.set_log_level(self.dev.LogLevel.ERR)
            try:
                prog = sp_.parse_prism_program(path, prism_compatibility=True)
            finally:
                self.dev.set_log_level(old)
        finally:
            os.unlink(path)
        return prog

    def _check(self, prog, value_type):
        sp_ = self.stormpy
        props = sp_.parse_properties('P=? [F "fin"]', prog)
        old = self.dev.get_log_level()
        self.dev.set_log_level(self.dev.LogLevel.ERR)
        try:
            model = sp_.build_model[value_type](prog, props)
            res = sp_.model_checking(model, props[0])
        finally:
            self.dev.set_log_level(old)
        return res.get_value(model.initial_states[0]), model.nr_states

    def p_fn_exact(self, p: ModuleParams) -> tuple[float, int]:
        val, n = self._check(self._program(prism_program(p)), self.stormpy.Rational)
        return float(val), n

    def p_fn_parametric(self, base: ModuleParams):
        """The rational function P[FN](pn, pc) (other parameters fixed) and an evaluator."""
        fn, n = self._check(self._program(prism_program(base, parametric=True)), self.stormpy.RationalFunction)
        variables = {v.name: v for v in fn.gather_variables()}
        coeff = self.stormpy.RationalFunctionCoefficient

        def evaluate(pn: Fraction, pc: Fraction) -> float:
            vals = {}
            for name, x in (("pn", pn), ("pc", pc)):
                if name in variables:
                    fr = Fraction(x)
                    vals[variables[name]] = coeff(f"{fr.numerator}/{fr.denominator}")
            return float(fn.evaluate(vals))

        return fn, evaluate, n
