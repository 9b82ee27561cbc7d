"""What the stress test meets: the encounters (a static object appearing a given number of
cycles of travel beyond the monitor's EBI curve, at a given speed, APPEAR_S after the train
entered) and the six sensor channels that report it (range, noise, where a ghost shows).
"""
from __future__ import annotations

from dataclasses import dataclass

from monitor.core.braking import curves
from monitor.core.config import Config


CHANNELS = 6
RANGE_M = 1000.0
NOISE_SIGMA_M = 0.5
GHOST_M = 200.0           # where a ghost is reported (beyond EBI: it can only add braking)
BEHIND_M = 300.0          # an object behind the obstacle (disturbances.P_BEHIND) stands this much farther
APPEAR_S = 2.0            # the obstacle appears this long after the train entered


@dataclass(frozen=True)
class Encounter:
    name: str
    speed_mps: float
    beyond_cycles: float      # the obstacle appears this many cycles of travel beyond EBI
    description: str

    def appear_m(self, cfg: Config) -> float:
        v = round(self.speed_mps * 100)
        ebi = curves(cfg, v, 0, 0, v, cfg.period_ms).ebi_dm / 10.0
        return round(ebi + self.beyond_cycles * self.speed_mps * cfg.period_ms / 1000.0, 1)


ENCOUNTERS = {e.name: e for e in (
    Encounter("edge-30", 30.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 30 m/s"),
    Encounter("edge-40", 40.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 40 m/s"),
    Encounter("edge-20", 20.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 20 m/s"),
)}
