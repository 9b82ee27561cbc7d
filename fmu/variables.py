"""The variables of the two FMUs, in one place: the XML model descriptions (FMI 2.0 and
3.0), the C value-reference header and the Python reference all come from these lists,
so they cannot drift apart. Value references are the list positions (0 is time)."""
from __future__ import annotations

from dataclasses import dataclass

from monitor.core.config import Config

CHANNELS = 6

TYPES = ("Real", "Integer", "Boolean", "String")
CAUSALITIES = ("parameter", "input", "output", "independent")
VARIABILITIES = ("constant", "fixed", "tunable", "discrete", "continuous")


@dataclass(frozen=True)
class Var:
    name: str
    type: str                  # Real, Integer, Boolean, String
    causality: str             # parameter, input, output, independent
    variability: str           # constant, fixed, tunable, discrete, continuous
    start: object = None       # None: initial="calculated" (outputs) / no start (time)
    unit: str | None = None
    description: str = ""
    min: float | None = None
    max: float | None = None

    @property
    def c_name(self) -> str:
        return "vr_" + self.name.replace(".", "_")


TIME = Var("time", "Real", "independent", "continuous", unit="s", description="simulation time")

_CFG = Config()

# The monitor's parameters: every Config field (same names, units in the names, same
# defaults and checks as monitor/core/config.py) except period_ms, which the table fixes
# (the constant output `period_ms`), and topology, an Integer parameter of its own.
PARAMETER_DOCS = {
    "timeout_cycles": "a report older than this many cycles is stale (timeout_cycles x 100 ms <= 60 s)",
    "persistence_cycles": "a 2oo2 disagreement this many cycles long is a perceptor error, 1..1000",
    "emergency_decel_mms2": "braking declaration: guaranteed emergency deceleration from standstill up "
                            "(speed band 1), mm/s^2, 1..20000",
    "emergency_band2_cms": "braking declaration: speed from which emergency band 2 applies, cm/s (0: no band 2)",
    "emergency_band2_mms2": "braking declaration: guaranteed emergency deceleration in band 2, mm/s^2, 1..20000",
    "emergency_band3_cms": "braking declaration: speed from which emergency band 3 applies, cm/s, above band 2 "
                           "(0: no band 3)",
    "emergency_band3_mms2": "braking declaration: guaranteed emergency deceleration in band 3, mm/s^2, 1..20000",
    "service_decel_mms2": "braking declaration: guaranteed service deceleration, mm/s^2, at most every emergency band's",
    "emergency_buildup_ms": "braking declaration: equivalent emergency brake build-up time (dead time + half the "
                            "ramp), ms, 0..30000",
    "service_buildup_ms": "braking declaration: equivalent service brake build-up time, ms, 0..30000",
    "traction_cutoff_ms": "braking declaration: time traction may still accelerate the train after a demand, ms, "
                          "0..30000",
    "max_accel_mms2": "braking declaration: largest acceleration under traction, mm/s^2, 0..5000",
    "speed_error_permille": "braking declaration: speed measurement error, per mille of the speed, 0..500",
    "slippery_permille": "braking declaration: deceleration factor while the train reports a slippery track, "
                         "per mille, 1..1000",
    "degraded_permille": "braking declaration: deceleration factor while the train reports degraded brakes, "
                         "per mille, 1..1000",
    "max_gradient_permille": "braking declaration: steepest downhill gradient of the line, per mille, 0..60",
    "standstill_margin_dm": "braking declaration: stop at least this far before the obstacle, dm, 0..10000",
    "warning_ms": "the warning curve leads SBI by this time, ms, 0..60000",
    "emergency_release": "1: an emergency is revocable once its cause is gone; 0: held to standstill",
    "release_confirm_cycles": "cycles in a row in which the causes ask for less before a held demand is lowered "
                              "(an emergency only if revocable), 1..1000",
    "warning_margin_dm": "table zones: warning zone length beyond alpha1, dm",
    "fast_closing_cms": "Model 2: closing speed from which an obstacle is fast, cm/s",
    "safe_reaction": "demand on a system error with a degraded channel or a bad train input: 1 service, 2 emergency",
    "recovery_cycles": "error-free cycles before DEGRADED or SAFE_STOP clear",
    "max_overruns": "consecutive deadline overruns leading to SAFE_STOP (the FMU never overruns), 1..1000",
    "distance_tolerance_dm": "2oo2: two PRESENT distances further apart than this raise the module flag, dm",
    "forget_ms": "obstacle memory: fresh unanimous ABSENT inside the sensor range this long forgets a remembered "
                 "obstacle, ms (rounded up to whole cycles), 1..600000",
    "sensor_range_dm": "obstacle memory: the sensors' declared range; absence counts as evidence only inside it, dm, "
                       "1..60000",
    "forget_single_ms": "obstacle memory: the same as forget_ms for an obstacle only one module ever saw (its "
                        "ghosts), ms (at most forget_ms counts), 1..600000",
    "distance_accuracy_dm": "error budget and plausibility: the sensors' declared distance accuracy (a report is "
                            "within this of the truth; the curves and the memory count it), dm, 0..60000",
    "closing_accuracy_cms": "error budget and plausibility: the sensors' declared closing-speed accuracy (the curves "
                            "and the memory count it), cm/s, 0..15000",
    "plausibility_ms": "plausibility: an implausible channel (its distance did not shrink as its closing speed "
                       "says) is believed again after this long of plausible reports, ms, 1..60000",
}
assert set(PARAMETER_DOCS) == set(Config._fields) - {"period_ms", "topology"}, "a Config field is not a parameter"
CONFIG_PARAMETERS = tuple(f for f in Config._fields if f in PARAMETER_DOCS)   # in Config's order
TOPOLOGY_CODES = {"3oo3": 3, "2oo2": 2}


def parameter_starts(cfg: Config) -> dict:
    """The monitor FMU's parameter start values for a configuration (topology as its code)."""
    starts = {name: getattr(cfg, name) for name in CONFIG_PARAMETERS}
    starts["topology"] = TOPOLOGY_CODES[cfg.topology]
    return starts


def _monitor() -> list[Var]:
    v = [TIME]
    for i in range(1, CHANNELS + 1):
        p = f"ch{i}."
        v += [
            Var(p + "status", "Integer", "input", "discrete", 0, None,
                f"channel {i} status: 0 ABSENT, 1 PRESENT, 2 DEGRADED; anything else counts as DEGRADED"),
            Var(p + "distance", "Real", "input", "continuous", 0.0, "m",
                f"channel {i} distance to the obstacle, 0..6000 m (read in dm, rounded down); NaN or out of range counts as DEGRADED"),
            Var(p + "closing_speed", "Real", "input", "continuous", 0.0, "m/s",
                f"channel {i} closing speed, positive when closing, -150..150 m/s (read in cm/s, rounded up)"),
            Var(p + "type", "Integer", "input", "discrete", 0, None,
                f"channel {i} obstacle type: 0 static, 1 dynamic, 2 train"),
            Var(p + "valid", "Boolean", "input", "discrete", False, None,
                f"channel {i} delivered a new report this step; false keeps the last one, which ages into DEGRADED"),
        ]
    v += [
        Var("train.speed", "Real", "input", "continuous", 0.0, "m/s",
            "train speed, 0..120 m/s (read in cm/s, rounded up); NaN or out of range is a train-input error"),
        Var("train.track_condition", "Integer", "input", "discrete", 0, None, "0 normal, 1 slippery"),
        Var("train.brake_status", "Integer", "input", "discrete", 0, None, "0 normal, 1 degraded"),
    ]
    for name in CONFIG_PARAMETERS:
        v.append(Var(name, "Integer", "parameter", "fixed", getattr(_CFG, name), None, PARAMETER_DOCS[name]))
    v.append(Var("topology", "Integer", "parameter", "fixed", 3, None,
                 "3: 3oo3 over three 2oo2 modules (channels 1-6); 2: one 2oo2 module (channels 1-2)"))
    v += [
        Var("brake_demand", "Integer", "output", "discrete", None, None,
            "0 none, 1 service, 2 emergency (emergency until every channel has been fresh once)"),
        Var("reasons", "Integer", "output", "discrete", None, None,
            "reason bits: 1 table, 2 envelope (inside EBI), 4 system_error, 8 latch, 16 init, 32 safe_stop, 64 stale, "
            "128 perceptor, 256 deadline, 512 train_input, 1024 sbi (inside SBI), 2048 warning, 4096 dispute, "
            "8192 memory (the curves supervise a remembered obstacle no channel shows); 8 latch: a demand held that no "
            "current cause asks for"),
        Var("voted_distance_dm", "Integer", "output", "discrete", None, None, "voted obstacle distance in dm; 65535: none"),
        Var("node", "Integer", "output", "discrete", None, None, "controller node of the policy table"),
        Var("mode", "Integer", "output", "discrete", None, None, "0 INIT, 1 NORMAL, 2 DEGRADED, 3 SAFE_STOP"),
        Var("module_flags", "Integer", "output", "discrete", None, None, "bit m: 2oo2 module m+1 raised its flag"),
        Var("system_error", "Boolean", "output", "discrete", None, None, "2oo2 flag, 3oo3 disagreement or train-input error"),
        Var("observation", "Integer", "output", "discrete", None, None, "observation index fed to the table"),
        Var("cycle", "Integer", "output", "discrete", None, None, "cycles run (saturates at 2^31-1)"),
        Var("error_cycles", "Integer", "output", "discrete", None, None, "cycles with an error or a stale channel"),
        Var("warning", "Boolean", "output", "discrete", None, None,
            "the supervision warns: voted obstacle inside the warning curve, or channels dispute an obstacle"),
        Var("track_dm", "Integer", "output", "discrete", None, None,
            "remembered obstacle's predicted (worst-case, nearest) distance in dm; 65535: none"),
        Var("track_cycles", "Integer", "output", "discrete", None, None,
            "cycles since the remembered obstacle was last voted (0 while it is seen)"),
        Var("track_state", "Integer", "output", "discrete", None, None,
            "obstacle memory this cycle: 0 none, 1 seen, 2 held, 3 confirming its absence, 4 forgotten, 5 passed"),
        Var("period_ms", "Integer", "output", "constant", _CFG.period_ms, None, "fixed internal cycle period, ms"),
        Var("table.model", "String", "output", "constant", "", None, "model the policy table was solved for"),
        Var("table.sha256", "String", "output", "constant", "", None,
            "SHA-256 stored in the table file's trailer, over the file before it (as railguard table show prints it)"),
        Var("table.nodes", "Integer", "output", "constant", 0, None, "number of controller nodes"),
        # the papers' risk, live (monitor/core/risk.py, docs/core.md): appended, so that the
        # value references above keep their numbers
        Var("r1_ppm", "Integer", "output", "discrete", None, None,
            "seed 000 eq. 16 at the nearest obstacle (voted or remembered), ppm: 500000 at the obstacle, "
            "0 without one; alpha1 = the service brake's EBI"),
        Var("r2_ppm", "Integer", "output", "discrete", None, None,
            "seed 000 eq. 17, ppm: (alpha1 - d) / (alpha1 - alpha2) clipped to [0, 10^6]; alpha2 = EBI"),
        Var("risk_score", "Integer", "output", "discrete", None, None,
            "seed 001 eq. 11: rho = 3 distance + 2 speed + 2 obstacle + track + 2 brake (levels from 0), 0..20"),
        Var("risk_category", "Integer", "output", "discrete", None, None,
            "seed 001's category of rho: 1 low (<= 7), 2 moderate (8-11), 3 high (12-15), 4 critical (>= 16)"),
        Var("table_risk_ppm", "Integer", "output", "discrete", None, None,
            "the table's risk column at the current node: P(hazard within 30 s | node), ppm"),
    ]
    return v


MONITOR = _monitor()
MONITOR_INPUTS = [v for v in MONITOR if v.causality == "input"]
MONITOR_OUTPUTS = [v for v in MONITOR if v.causality == "output" and v.variability != "constant"]
PARAMETERS = [v for v in MONITOR if v.causality == "parameter"]


def _train() -> list[Var]:
    v = [TIME]
    P = "parameter"
    v += [
        Var("brake_demand", "Integer", "input", "discrete", 0, None, "brake demand read from the monitor: 0 none, 1 service, 2 emergency"),
        Var("monitor_cycle", "Integer", "input", "discrete", 0, None,
            "the monitor's alive counter (connect the monitor's `cycle`): the brakes apply (emergency, held to "
            "standstill) when it has not changed for brake_timeout after the 1 s hand-over"),
        Var("initial_speed", "Real", P, "fixed", 20.0, "m/s", "train speed at t = 0", 0.0, 120.0),
        Var("mass", "Real", P, "fixed", 400000.0, "kg", "train mass", 1.0),
        Var("davis_a", "Real", P, "fixed", 6000.0, "N", "Davis resistance, constant term", 0.0),
        Var("davis_b", "Real", P, "fixed", 100.0, "N.s/m", "Davis resistance, term in v", 0.0),
        Var("davis_c", "Real", P, "fixed", 8.0, "N.s2/m2", "Davis resistance, term in v^2", 0.0),
        Var("gradient", "Real", P, "fixed", 0.0, None, "track gradient in per mille, positive uphill", -60.0, 60.0),
        Var("max_traction", "Real", P, "fixed", 0.5, "m/s2", "traction acceleration available to hold the cruising speed", 0.0),
        Var("cruise_speed", "Real", P, "fixed", -1.0, "m/s", "speed the cruise controller holds; above initial_speed the train pulls at up to max_traction until it gets there; negative: initial_speed", None, 120.0),
        Var("service_decel", "Real", P, "fixed", 1.0, "m/s2", "deceleration of service braking", 0.0),
        Var("emergency_decel", "Real", P, "fixed", 3.0, "m/s2", "deceleration of emergency braking (below emergency_band2_speed, if set)", 0.0),
        Var("emergency_band2_speed", "Real", P, "fixed", 0.0, "m/s", "emergency braking uses emergency_band2_decel from this speed (0: no band 2)", 0.0),
        Var("emergency_band2_decel", "Real", P, "fixed", 0.0, "m/s2", "deceleration of emergency braking in band 2", 0.0),
        Var("emergency_band3_speed", "Real", P, "fixed", 0.0, "m/s", "emergency braking uses emergency_band3_decel from this speed (0: no band 3)", 0.0),
        Var("emergency_band3_decel", "Real", P, "fixed", 0.0, "m/s2", "deceleration of emergency braking in band 3", 0.0),
        Var("brake_delay", "Real", P, "fixed", 0.2, "s", "dead time before the brakes react to a new demand", 0.0),
        Var("brake_buildup", "Real", P, "fixed", 0.5, "s", "time for the brake force to ramp from zero to full", 0.0),
        Var("traction_cutoff", "Real", P, "fixed", -1.0, "s",
            "full traction this long after a brake demand, then none; negative: the cruise traction is cut when the brake level applies", None, 30.0),
        Var("speed_error", "Real", P, "fixed", 0.0, None, "train.speed reports the true speed / (1 + speed_error): low by this fraction of itself", 0.0, 0.5),
        Var("track_condition", "Integer", P, "fixed", 0, None, "0 normal, 1 slippery (reported to the monitor)"),
        Var("brake_status", "Integer", P, "fixed", 0, None, "0 normal, 1 degraded (reported to the monitor)"),
        Var("slippery_factor", "Real", P, "fixed", 1.0, None, "brake decelerations are multiplied by this while track_condition = 1", 0.0, 1.0),
        Var("degraded_factor", "Real", P, "fixed", 1.0, None, "brake decelerations are multiplied by this while brake_status = 1", 0.0, 1.0),
        Var("obstacle.present", "Boolean", P, "fixed", True, None, "an obstacle is on the track"),
        Var("obstacle.position", "Real", P, "fixed", 500.0, "m", "obstacle position at t = 0, measured from the train's start", 0.0),
        Var("obstacle.speed", "Real", P, "fixed", 0.0, "m/s", "obstacle speed along the track (0: static)"),
        Var("obstacle.type", "Integer", P, "fixed", 0, None, "0 static, 1 dynamic, 2 train"),
        Var("obstacle.leave_time", "Real", P, "fixed", 1e9, "s",
            "the obstacle leaves the track at this time (a vehicle clearing a level crossing): from then on the "
            "sensors do not see it and the train cannot reach it; 1e9: never", 0.0),
        Var("sensor.range", "Real", P, "fixed", 400.0, "m", "sensors see an obstacle closer than this", 0.0),
        Var("sensor.noise_sigma", "Real", P, "fixed", 0.3, "m", "standard deviation of the Gaussian distance noise", 0.0),
        Var("sensor.miss_probability", "Real", P, "fixed", 0.0, None, "probability that a channel misses a visible obstacle in a sample", 0.0, 1.0),
        Var("sensor.distance_bias", "Real", P, "fixed", 0.0, "m", "systematic error added to every reported distance "
            "(a sensor that errs inside its declared accuracy: + reports the obstacle farther)"),
        Var("sensor.closing_bias", "Real", P, "fixed", 0.0, "m/s", "systematic error added to every reported closing "
            "speed (- reports the obstacle closing slower)"),
        Var("sensor.period", "Real", P, "fixed", 0.1, "s", "sensor reporting period", 0.01),
        Var("sensor.seed", "Integer", P, "fixed", 1, None, "seed of the sensor noise (same seed, same run)"),
        Var("fault.kind", "Integer", P, "fixed", 0, None,
            "0 none, 1 silence, 2 stuck value, 3 noise burst, 4 missed detection, 5 degraded status, 6 out-of-range distance (NaN), 7 contradiction, "
            "8 blind (every channel misses at once)"),
        Var("fault.channel", "Integer", P, "fixed", 1, None, "channel 1..6 the fault hits"),
        Var("fault.start", "Real", P, "fixed", 0.0, "s", "fault begins"),
        Var("fault.end", "Real", P, "fixed", 1e9, "s", "fault ends"),
        Var("brake_timeout", "Real", P, "fixed", 0.3, "s",
            "the brake receiver's alive timeout: emergency, held to standstill, once monitor_cycle has not changed "
            "for this long (3 monitor periods, the supervision's timing contract); 0: no alive check", 0.0, 10.0),
    ]
    for i in range(1, CHANNELS + 1):
        p = f"ch{i}."
        v += [
            Var(p + "status", "Integer", "output", "discrete", None, None, f"channel {i} status: 0 ABSENT, 1 PRESENT, 2 DEGRADED"),
            Var(p + "distance", "Real", "output", "discrete", None, "m", f"channel {i} measured distance"),
            Var(p + "closing_speed", "Real", "output", "discrete", None, "m/s", f"channel {i} measured closing speed"),
            Var(p + "type", "Integer", "output", "discrete", None, None, f"channel {i} obstacle type"),
            Var(p + "valid", "Boolean", "output", "discrete", None, None, f"channel {i} sent a report in this step"),
        ]
    v += [
        Var("train.speed", "Real", "output", "continuous", None, "m/s", "train speed as reported to the monitor (true_speed / (1 + speed_error))"),
        Var("train.track_condition", "Integer", "output", "discrete", None, None, "0 normal, 1 slippery"),
        Var("train.brake_status", "Integer", "output", "discrete", None, None, "0 normal, 1 degraded"),
        Var("true_speed", "Real", "output", "continuous", None, "m/s", "train speed"),
        Var("position", "Real", "output", "continuous", None, "m", "train position"),
        Var("acceleration", "Real", "output", "continuous", None, "m/s2", "train acceleration"),
        Var("true_distance", "Real", "output", "continuous", None, "m", "true distance to the obstacle (1e9 with no obstacle)"),
        Var("brake_level", "Integer", "output", "discrete", None, None, "brake level in effect after the brake delay"),
        Var("brake_decel", "Real", "output", "continuous", None, "m/s2", "brake deceleration acting now"),
        Var("collided", "Boolean", "output", "discrete", None, None, "train and obstacle met (see impact_speed)"),
        Var("impact_speed", "Real", "output", "discrete", None, "m/s",
            "our speed when train and obstacle met: > 0 a collision, 0 an oncoming obstacle reached a standing train"),
        Var("receiver_brake", "Boolean", "output", "discrete", None, None,
            "the brake receiver holds an emergency: monitor_cycle stopped changing for brake_timeout"),
    ]
    return v


TRAIN = _train()
UNITS = ("m", "m/s", "m/s2", "s", "kg", "N", "N.s/m", "N.s2/m2")
