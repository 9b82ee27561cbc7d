"""One 2oo2 obstacle-detection module as the CTMC of seed 002's Listing 5.

`ModuleParams` holds the misclassification, voter, sensor and communication probabilities
and the documented choices where the listing is silent; `build_chain` explores the
reachable states from the initial one, with symbolic transition weights, so that one chain
serves every parameter set.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .numbers import PAPER_P


ACTIONS = ("gen", "sense_c", "sense_n", "perc_c", "perc_n", "com_c", "com_n", "vote")


@dataclass(frozen=True)
class ModuleParams:
    """Parameters of one 2oo2 OD module (seed 002 Listing 5).

    p_n, p_c: residual misclassification probability of the NN / conventional perceptor:
        given a hazardous picture (obstacle, or degraded data), it reports 'clear' (0).
    p_v: the voter's failure probability per vote, split into three equally likely
        failure modes as in Listing 5 (lines 16-19 and 22-25).
    p_s: probability of an undetected sensor fault per sensing action (CS, SS_sh, a
        missed degradation SS_di): the sensor forwards a clear picture.
    p_com: probability of a faulty communication (CC, SC): the voter receives 'clear'.
    q_obs: probability that a demand is an obstacle (d = 1) rather than degraded data (d = 2).
    rates: action rates lambda_a (footnote 12: 1 where unknown), as ((action, rate), ...).
    guards: 'disjoint' (the agreement command of the voter applies only where the
        contradiction command does not) or 'race' (Listing 5's guards literally; where
        both hold, PRISM's CTMC semantics races the two commands).
    degraded: 'perceptor' (a degraded picture is a hazard class the perceptor must
        recognise, with the same p_f^i) or 'sensor' (only the sensor's self-check, p_s,
        can miss degraded data; the perceptor passes a flagged picture through).
    fin: 'paper' (seed 002's predicate), 'wrong' (flag muted and r != d) or
        'clear' (flag muted and r = 0, the wording of H_OD).
    """
    p_n: float = PAPER_P
    p_c: float = PAPER_P
    p_v: float = 1e-6
    p_s: float = 1e-6
    p_com: float = 1e-6
    q_obs: float = 0.5
    rates: tuple = ()
    guards: str = "disjoint"
    degraded: str = "perceptor"
    fin: str = "paper"

    def rate(self, action: str) -> float:
        return dict(self.rates).get(action, 1.0)

    def factors(self) -> dict[str, float]:
        return {"1": 1.0, "q": self.q_obs, "1-q": 1 - self.q_obs,
                "ps": self.p_s, "1-ps": 1 - self.p_s, "pcom": self.p_com, "1-pcom": 1 - self.p_com,
                "pc": self.p_c, "1-pc": 1 - self.p_c, "pn": self.p_n, "1-pn": 1 - self.p_n,
                "pv/3": self.p_v / 3, "1-pv": 1 - self.p_v}


# state: (d, sc, sn, senc, senn, perc, pern, comc, comn, r, f)
D, SC, SN, SENC, SENN, PERC, PERN, COMC, COMN, R, F = range(11)
INIT = (0, 0, 0, 0, 0, 0, 0, 0, 0, 0, False)
CHANNELS = {"c": (SC, SENC, PERC, COMC), "n": (SN, SENN, PERN, COMN)}


def _set(s: tuple, **kv) -> tuple:
    idx = {"d": D, "sc": SC, "sn": SN, "senc": SENC, "senn": SENN, "perc": PERC, "pern": PERN,
           "comc": COMC, "comn": COMN, "r": R, "f": F}
    t = list(s)
    for k, v in kv.items():
        t[idx[k]] = v
    return tuple(t)


def _successors(s: tuple, guards: str, degraded: str) -> list[tuple[str, str, tuple]]:
    """(action, factor, next state) of every transition out of s; rate = lambda_action * factor."""
    out: list[tuple[str, str, tuple]] = []
    if s[D] == 0 and s[SC] == 0 and s[SN] == 0:                      # Generate (synchronised)
        out.append(("gen", "q", _set(s, d=1, sc=1, sn=1)))
        out.append(("gen", "1-q", _set(s, d=2, sc=1, sn=1)))
        return out
    for ch, (st, sen, per, com) in CHANNELS.items():                 # channels interleave
        stage = s[st]

        def put(**kv):
            t = list(s)
            for k, v in kv.items():
                t[{"st": st, "sen": sen, "per": per, "com": com}[k]] = v
            return tuple(t)

        pf = "p" + ch
        if stage == 1:                                               # Sense_i
            out.append((f"sense_{ch}", "1-ps", put(st=2, sen=s[D])))
            out.append((f"sense_{ch}", "ps", put(st=2, sen=0)))
        elif stage == 2:                                             # Perceive_i
            if s[sen] == 1 or (s[sen] == 2 and degraded == "perceptor"):
                out.append((f"perc_{ch}", "1-" + pf, put(st=3, per=s[sen])))
                out.append((f"perc_{ch}", pf, put(st=3, per=0)))
            else:                                                    # clear, or flagged degraded
                out.append((f"perc_{ch}", "1", put(st=3, per=s[sen])))
        elif stage == 3:                                             # Communicate_i
            out.append((f"com_{ch}", "1-pcom", put(st=4, com=s[per])))
            out.append((f"com_{ch}", "pcom", put(st=4, com=0)))
    if s[SC] == 4 and s[SN] == 4:                                    # Vote (synchronised)
        cc, cn = s[COMC], s[COMN]
        contradiction = cc == 2 or cn == 2 or cc != cn              # Listing 5 line 15 (UC)
        agreement = cc == 1 or cc == cn                              # Listing 5 line 21 (S)
        if guards == "disjoint":
            agreement = agreement and not contradiction
        done = dict(sc=5, sn=5)
        if contradiction:
            out.append(("vote", "1-pv", _set(s, f=True, r=max(cc, cn), **done)))
            for r in (0, 1, 2):
                out.append(("vote", "pv/3", _set(s, f=False, r=r, **done)))
        if agreement:
            out.append(("vote", "1-pv", _set(s, f=False, r=cc, **done)))
            out.append(("vote", "pv/3", _set(s, f=True, **done)))
            out.append(("vote", "pv/3", _set(s, f=False, r=0, **done)))
            out.append(("vote", "pv/3", _set(s, f=False, r=2, **done)))
    return out


def _is_fin(s: tuple, fin: str) -> bool:
    if not (s[SC] == 5 and s[SN] == 5 and not s[F]):
        return False
    if fin == "paper":
        return s[COMC] != s[COMN] or (s[COMC] == s[COMN] and s[R] != s[D])
    if fin == "wrong":
        return s[R] != s[D]
    if fin == "clear":
        return s[R] == 0
    raise ValueError(fin)


@dataclass
class Chain:
    """The reachable state space and its transitions, with symbolic weights."""
    states: list
    src: np.ndarray
    dst: np.ndarray
    action: list
    factor: list
    fin: np.ndarray          # bool per state
    od: np.ndarray           # indices of S_od (s_c = s_n = 1, d in {1, 2})
    absorbing: np.ndarray    # bool per state (no outgoing transition)
    keys: list = field(default_factory=list)
    key_idx: np.ndarray | None = None


@lru_cache(maxsize=None)
def build_chain(guards: str = "disjoint", degraded: str = "perceptor", fin: str = "paper") -> Chain:
    """Explore the reachable states from INIT (breadth first)."""
    index = {INIT: 0}
    states = [INIT]
    src, dst, act, fac = [], [], [], []
    i = 0
    while i < len(states):
        s = states[i]
        for a, k, t in _successors(s, guards, degraded):
            if t not in index:
                index[t] = len(states)
                states.append(t)
            src.append(i)
            dst.append(index[t])
            act.append(a)
            fac.append(k)
        i += 1
    n = len(states)
    has_out = np.zeros(n, dtype=bool)
    has_out[np.asarray(src)] = True
    keys = sorted(set(fac))
    chain = Chain(states=states, src=np.asarray(src), dst=np.asarray(dst), action=act, factor=fac,
                  fin=np.array([_is_fin(s, fin) for s in states]),
                  od=np.array([j for j, s in enumerate(states) if s[SC] == 1 and s[SN] == 1 and s[D] in (1, 2)]),
                  absorbing=~has_out, keys=keys)
    chain.key_idx = np.array([keys.index(k) for k in fac])
    return chain
