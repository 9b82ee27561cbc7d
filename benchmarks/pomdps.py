"""Public point-based benchmark POMDPs, generated from their published definitions.

- RockSample[n, k] (Smith & Simmons, "Heuristic search value iteration for POMDPs", UAI
  2004, section 6): an n x n grid, k rocks of unknown quality (good/bad, prior 1/2 each).
  Moves north/east/south/west; moving off the east edge pays +10 and ends the episode;
  sampling at a rock pays +10 if good (the rock turns bad) and -10 if bad; check_i returns
  the rock's quality correctly with probability (1 + eta) / 2, eta = 2^(-d / d0) for
  distance d. Illegal acts (moving off another edge, sampling where there is no rock) pay
  -100 and end the episode, as in the authors' generator of the benchmark files. The
  [5, 5] instance (801 states) uses the authors' published layout: start (0, 2), rocks at
  (2, 4), (0, 4), (3, 3), (2, 2), (4, 1), d0 = 4.
- Tag (Pineau, Gordon & Thrun, "Point-based value iteration: an anytime algorithm for
  POMDPs", IJCAI 2003, section 5.2): 29 cells (two rows of 10, a 3 x 3 block on columns
  5-7 above them); robot and opponent start uniformly and independently; the robot's moves
  are deterministic (-1 each), `tag` pays +10 in the opponent's cell (then absorbing,
  "tagged") and -10 elsewhere. The opponent moves away from the robot: 0.4 along x, 0.4
  along y (both directions when level, 0.2 each), a move into a wall leaves it in place,
  and it stays with 0.2. The robot observes its own cell, or "same" when the opponent
  shares it. States: 29 robot cells x (29 opponent cells + tagged) = 870.

Discount 0.95 for all. Written from these descriptions (no code copied).
"""
from __future__ import annotations

import math

import numpy as np

from monitor.offline.pomdp import POMDP

RS55 = dict(n=5, start=(0, 2), rocks=((2, 4), (0, 4), (3, 3), (2, 2), (4, 1)), half_efficiency=4.0)


def rocksample(n: int, start: tuple, rocks: tuple, half_efficiency: float, discount: float = 0.95) -> POMDP:
    """RockSample[n, len(rocks)]; state index (x * n + y) * 2^k + r, terminal last; bit
    (k - 1 - i) of r is rock i being good."""
    k = len(rocks)
    R2 = 2 ** k
    S = n * n * R2 + 1
    END = S - 1
    moves = {"north": (0, 1), "east": (1, 0), "south": (0, -1), "west": (-1, 0)}
    actions = list(moves) + [f"check{i}" for i in range(k)] + ["sample"]
    A = len(actions)
    T = np.zeros((A, S, S))
    O = np.zeros((A, S, 2))          # observations: good, bad
    O[:, :, 0] = 1.0                 # everything but a check reads "good"
    R = np.zeros((S, A))
    T[:, END, END] = 1.0

    def index(x, y, r):
        return (x * n + y) * R2 + r

    rock_at = {pos: i for i, pos in enumerate(rocks)}
    for x in range(n):
        for y in range(n):
            for r in range(R2):
                s = index(x, y, r)
                for a, (dx, dy) in enumerate(moves.values()):
                    xp, yp = x + dx, y + dy
                    if xp >= n:
                        T[a, s, END], R[s, a] = 1.0, 10.0
                    elif not (0 <= xp < n and 0 <= yp < n):
                        T[a, s, END], R[s, a] = 1.0, -100.0
                    else:
                        T[a, s, index(xp, yp, r)] = 1.0
                for i, (rx, ry) in enumerate(rocks):
                    a = 4 + i
                    T[a, s, s] = 1.0
                    eta = math.exp(-math.hypot(x - rx, y - ry) * math.log(2) / half_efficiency)
                    good = (r >> (k - 1 - i)) & 1
                    p_good = eta * good + (1 - eta) * 0.5
                    O[a, s] = (p_good, 1.0 - p_good)
                a = A - 1
                if (x, y) in rock_at:
                    mask = 1 << (k - 1 - rock_at[(x, y)])
                    R[s, a] = 10.0 if r & mask else -10.0
                    T[a, s, index(x, y, r & ~mask)] = 1.0
                else:
                    T[a, s, END], R[s, a] = 1.0, -100.0
    b0 = np.zeros(S)
    b0[[index(start[0], start[1], r) for r in range(R2)]] = 1.0 / R2
    states = [f"s{x}{y}_{r:0{k}b}" for x in range(n) for y in range(n) for r in range(R2)] + ["end"]
    return POMDP(f"RockSample[{n},{k}]", tuple(states), tuple(actions), ("good", "bad"), T, O, R, discount, b0)


def tag_cells() -> list[tuple[int, int]]:
    """The 29 cells (x, y): rows y = 0, 1 of x = 0..9, then the block x = 5..7, y = 2..4."""
    return [(x, y) for y in range(2) for x in range(10)] + [(x, y) for y in range(2, 5) for x in range(5, 8)]


def tag(discount: float = 0.95) -> POMDP:
    """Tag; state index robot * 30 + opponent, opponent 29 meaning tagged."""
    cells = tag_cells()
    C = len(cells)
    where = {c: i for i, c in enumerate(cells)}
    S, TAGGED = C * (C + 1), C
    names = ("north", "south", "east", "west", "tag")
    step = {"north": (0, 1), "south": (0, -1), "east": (1, 0), "west": (-1, 0)}

    def moved(i, d):
        x, y = cells[i]
        return where.get((x + d[0], y + d[1]), i)

    def opponent_moves(rob, opp):
        """{next opponent cell: probability}."""
        (rx, ry), (ox, oy) = cells[rob], cells[opp]
        out = {opp: 0.2}
        for axis, (mine, theirs) in enumerate(((rx, ox), (ry, oy))):
            away = [+1] if theirs > mine else [-1] if theirs < mine else [+1, -1]
            for sign in away:
                d = (sign, 0) if axis == 0 else (0, sign)
                nxt = moved(opp, d)
                out[nxt] = out.get(nxt, 0.0) + 0.4 / len(away)
        return out

    A = len(names)
    T = np.zeros((A, S, S))
    R = np.zeros((S, A))
    for rob in range(C):
        for opp in range(C + 1):
            s = rob * (C + 1) + opp
            for a, name in enumerate(names):
                if opp == TAGGED:
                    T[a, s, s] = 1.0
                    continue
                if name == "tag" and rob == opp:
                    T[a, s, rob * (C + 1) + TAGGED], R[s, a] = 1.0, 10.0
                    continue
                R[s, a] = -10.0 if name == "tag" else -1.0
                rob2 = rob if name == "tag" else moved(rob, step[name])
                for opp2, p in opponent_moves(rob, opp).items():
                    T[a, s, rob2 * (C + 1) + opp2] += p
    O = np.zeros((A, S, C + 1))      # observation: the robot's cell, or C = "same cell"
    for rob in range(C):
        for opp in range(C + 1):
            O[:, rob * (C + 1) + opp, C if opp == rob else rob] = 1.0
    b0 = np.zeros(S)
    for rob in range(C):
        b0[rob * (C + 1): rob * (C + 1) + C] = 1.0 / (C * C)
    states = tuple(f"r{r}_{'tagged' if o == TAGGED else f'o{o}'}" for r in range(C) for o in range(C + 1))
    obs = tuple(f"at{c}" for c in range(C)) + ("same",)
    return POMDP("Tag", states, names, obs, T, O, R, discount, b0)
