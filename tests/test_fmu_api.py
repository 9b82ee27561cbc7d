"""The FMUs at their FMI interface, as an importer sees them (issue 5).

The three monitor FMUs and the train FMU pass FMPy's validation; they carry their sources,
and the FMI 2.0 monitor rebuilds from them with FMPy's own builder; the read-only table
values are right; a wrong calling sequence or a bad parameter is refused with fmiError
and a logged message naming the function or variable; NaN and out-of-range inputs count
as DEGRADED exactly as in the Python reference; the C table check refuses a corrupted
table and its SHA-256 agrees with hashlib; the train FMU runs, brakes, refuses bad
parameters and repeats its noise for a seed.

Log messages are received with our own logger callback. For FMI 3.0 that is FMPy's
`instantiate(logMessage=...)`. For FMI 2.0 we pass our own `fmi2CallbackFunctions` and do
not install FMPy's `addLoggerProxy`: the proxy keeps one logger for the whole process (a
C global), so installing it would redirect every other FMU's messages to ours. Our
wrappers never pass printf arguments; they only double '%' and '#' in the text, which
`_plain` undoes.
"""
from __future__ import annotations

import hashlib
import math
import random
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.build import build_platform_binary
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from fmu import generate
from fmu.build import C_DIR, CFLAGS, BuildError, build_monitor, compiler
from fmu.driver import MonitorDriver, vr_of
from fmu.reference import CHANNELS, ChannelInput, MonitorReference, StepInput, config_from_parameters
from fmu.variables import MONITOR, MONITOR_OUTPUTS, TRAIN
from monitor.core.config import DECLARATION_FIELDS, Config, ConfigurationError, check
from monitor.core.table import decode
from monitor.tables import read

ERROR = 3                      # fmi2Error == fmi3Error
MONITOR_KEYS = [("m1", 2), ("m2", 2), ("m1", 3)]
OUT_NAMES = [v.name for v in MONITOR_OUTPUTS]
R_STALE, R_TRAIN_INPUT = 64, 512
NORMAL, DEGRADED = 1, 2


def _id(key) -> str:
    return key if isinstance(key, str) else f"{key[0]}-fmi{key[1]}"


# ---- an FMU instance with its log ---------------------------------------------------------

def _plain(text: str) -> str:
    return text.replace("%%", "%").replace("##", "#")


class Instance:
    """One instantiated FMU (FMI 2.0 or 3.0) whose logged messages go to `self.log`
    as (status, category, text); variables are addressed by name."""

    def __init__(self, unzip: Path, variables, name: str = "api"):
        md = read_model_description(str(unzip))
        self.fmi = 3 if md.fmiVersion.startswith("3") else 2
        self.variables = variables
        self.log: list[tuple[int, str, str]] = []
        kwargs = dict(unzipDirectory=str(unzip), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=name)
        if self.fmi == 2:
            self.slave = FMU2Slave(guid=md.guid, **kwargs)
            self._callbacks = fmi2CallbackFunctions()
            self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log2)
            self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
            self._callbacks.freeMemory = defaultCallbacks.freeMemory
            self.slave.instantiate(callbacks=self._callbacks)
        else:
            self.slave = FMU3Slave(guid=md.instantiationToken, **kwargs)
            self.slave.instantiate(logMessage=self._log3)
        self.time = 0.0

    def _log2(self, env, instance, status, category, message):
        self.log.append((status, category.decode(), _plain(message.decode())))

    def _log3(self, env, status, category, message):
        self.log.append((status, category.decode(), message.decode().replace("##", "#")))

    def fn(self, name: str) -> str:
        """The FMI function name as the FMU logs it, e.g. fn('DoStep') -> 'fmi2DoStep'."""
        return f"fmi{self.fmi}{name}"

    def _accessor(self, direction: str, kind: str):
        kind = kind if self.fmi == 2 else {"Real": "Float64", "Integer": "Int32"}.get(kind, kind)
        return getattr(self.slave, f"{direction}{kind}")

    def vr(self, name: str) -> int:
        return vr_of(self.variables, name)

    def get(self, name: str):
        kind = self.variables[self.vr(name)].type
        value = self._accessor("get", kind)([self.vr(name)])[0]
        if kind == "Boolean":
            return bool(value)
        return value.decode() if isinstance(value, bytes) else value

    def set(self, name: str, value) -> None:
        self._accessor("set", self.variables[self.vr(name)].type)([self.vr(name)], [value])

    def enter_init(self) -> None:
        if self.fmi == 2:
            self.slave.setupExperiment(startTime=0.0)
            self.slave.enterInitializationMode()
        else:
            self.slave.enterInitializationMode(startTime=0.0)

    def init(self, params: dict | None = None) -> None:
        self.enter_init()
        for name, value in (params or {}).items():
            self.set(name, value)
        self.slave.exitInitializationMode()
        self.time = 0.0

    def step(self, h: float) -> None:
        self.slave.doStep(self.time, h)
        self.time = round(self.time + h, 9)

    def refused(self, call, *args) -> str:
        """Run a call that must return fmiError; the error messages it logged, joined."""
        before = len(self.log)
        with pytest.raises(FMICallException) as exc:
            call(*args)
        assert exc.value.status == ERROR
        text = " | ".join(m for status, category, m in self.log[before:] if status == ERROR)
        assert text, f"{exc.value} but nothing was logged at error level"
        return text

    def close(self) -> None:
        self.slave.freeInstance()


@pytest.fixture(scope="module")
def unzipped(monitor_fmus, train_fmu):
    """Each FMU extracted once: {("m1", 2): dir, ..., "train": dir}."""
    dirs = {key: Path(extract(str(path))) for key, path in monitor_fmus.items()}
    dirs["train"] = Path(extract(str(train_fmu)))
    yield dirs
    for d in dirs.values():
        shutil.rmtree(d, ignore_errors=True)


@pytest.fixture
def instance(unzipped):
    """A factory of fresh instances, freed after the test."""
    made = []

    def make(key, variables=None):
        inst = Instance(unzipped[key], variables or (TRAIN if key == "train" else MONITOR))
        made.append(inst)
        return inst

    yield make
    for inst in made:
        inst.close()


# ---- 1, 2: validation, sources, rebuild -----------------------------------------------------

def test_fmpy_validation_finds_no_problem(monitor_fmus, train_fmu):
    """FMPy's validator reports nothing for the three monitor FMUs and the train FMU."""
    for path in [*monitor_fmus.values(), train_fmu]:
        assert validate_fmu(str(path)) == [], path.name


@pytest.mark.parametrize("key", [*MONITOR_KEYS, "train"], ids=_id)
def test_the_archive_carries_its_sources_and_the_binary_where_fmi_says(key, monitor_fmus, train_fmu):
    """The binary is at binaries/<FMI platform>/<identifier>.so; the source files the model
    description (FMI 2.0) or sources/buildDescription.xml (FMI 3.0) lists are all in the
    archive, and together they are every .c file shipped."""
    path = train_fmu if key == "train" else monitor_fmus[key]
    identifier = "railguard_train" if key == "train" else "railguard_monitor"
    fmi = 2 if key == "train" else key[1]
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert f"binaries/{'linux64' if fmi == 2 else 'x86_64-linux'}/{identifier}.so" in names
    md = read_model_description(str(path))
    assert md.fmiVersion.startswith(str(fmi))
    if fmi == 3:
        assert "sources/buildDescription.xml" in names
    (config,) = md.buildConfigurations
    assert config.modelIdentifier == identifier
    (files,) = [s.sourceFiles for s in config.sourceFileSets]
    assert f"fmi{fmi}.c" in files
    assert {f"sources/{f}" for f in files} == {n for n in names if n.startswith("sources/") and n.endswith(".c")}
    for header in ("model.h", "config.h", "variables.h") + (("rg_table.h", "rg_core.h") if key != "train" else ()):
        assert f"sources/{header}" in names


def _approach() -> list[tuple[StepInput, int]]:
    """A short input sequence that goes through NORMAL, a NaN channel (DEGRADED) and the
    envelope: (inputs, cycles) per communication step."""
    steps = []
    for k in range(12):
        distance = 500.0 - 45.0 * k
        ch = ChannelInput(1, distance, 20.0, 0, True)
        chans = [ch] * CHANNELS
        if k == 4:
            chans[2] = ch._replace(distance=math.nan)
        steps.append((StepInput(tuple(chans), 20.0), 2 if k % 3 == 2 else 1))
    return steps


@pytest.mark.parametrize("key", [("m1", 2), ("m1", 3)], ids=_id)
def test_fmpy_rebuilds_the_monitor_from_the_fmus_own_sources(key, monitor_fmus, tmp_path):
    """So that others can compile it: with the binary deleted, FMPy's CMake builder
    compiles the FMU from nothing but its sources and FMPy's FMI headers; the rebuilt FMU
    simulates with fmpy.simulate_fmu and its outputs equal the original's step for step."""
    original = monitor_fmus[key]
    unzip = tmp_path / "unzipped"
    with zipfile.ZipFile(original) as zf:
        zf.extractall(unzip)
    binary = unzip / "binaries" / ("linux64" if key[1] == 2 else "x86_64-linux") / "railguard_monitor.so"
    binary.unlink()
    build_dir = tmp_path / "build"
    build_dir.mkdir()
    build_platform_binary(unzip.resolve(), build_dir=build_dir)
    assert binary.is_file()
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as zf:
        for f in sorted(unzip.rglob("*")):
            if f.is_file():
                zf.write(f, f.relative_to(unzip).as_posix())

    runs = [simulate_fmu(str(p), stop_time=1.0, output_interval=0.1, output=["brake_demand", "mode", "cycle"])
            for p in (original, rebuilt)]
    assert list(runs[1]["cycle"]) == list(range(11))
    assert runs[0].tolist() == runs[1].tolist()

    drivers = [MonitorDriver(p) for p in (original, rebuilt)]
    try:
        ref = MonitorReference(read(key[0]))
        seen = []
        for inp, cycles in _approach():
            want = tuple(ref.step(inp, cycles)[-1])
            for d in drivers:
                d.set(inp)
            got = [d.step(cycles) for d in drivers]
            assert got[1] == got[0] == want
            seen.append(dict(zip(OUT_NAMES, got[1])))
    finally:
        for d in drivers:
            d.close()
    # the sequence exercised something: NORMAL with no demand, DEGRADED, the envelope
    assert {s["mode"] for s in seen} >= {NORMAL, DEGRADED}
    assert {s["brake_demand"] for s in seen} >= {0, 2}
    assert any(s["reasons"] & 2 for s in seen)


# ---- 3: read-only values ----------------------------------------------------------------------

@pytest.mark.parametrize("key", MONITOR_KEYS, ids=_id)
def test_table_identity_is_readable(key, instance):
    """table.sha256, table.model, table.nodes and period_ms tell which table the FMU runs.
    table.sha256 is the table's digest as decode() reports it: SHA-256 of the content before
    the 32-byte trailer (which is also the trailer), not `sha256sum` of the whole file."""
    table = decode(read(key[0]))
    fmu = instance(key)
    fmu.init()
    assert fmu.get("table.sha256") == table.sha256 == hashlib.sha256(read(key[0])[:-32]).hexdigest()
    assert fmu.get("table.model") == key[0]
    assert fmu.get("table.nodes") == table.nodes
    assert fmu.get("period_ms") == 100
    assert fmu.get("node") == table.start
    fmu.step(0.1)  # constants stay constant
    assert fmu.get("table.sha256") == table.sha256 and fmu.get("table.nodes") == table.nodes


# ---- 4: wrong calling sequence ----------------------------------------------------------------

WRONG_CALLS = ["step_before_init", "set_output", "set_fixed_parameter", "step_zero", "step_negative",
               "wrong_time", "unknown_vr", "wrong_type"]


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("case", WRONG_CALLS)
def test_a_wrong_call_is_an_error_with_a_message(case, fmi, instance):
    """Every misuse returns fmiError (never crashes, never silently succeeds) and logs a
    message that names the function and, where there is one, the variable."""
    fmu = instance(("m1", fmi))
    if case != "step_before_init":
        fmu.init()
        fmu.step(0.1)
    if case == "step_before_init":
        text = fmu.refused(fmu.slave.doStep, 0.0, 0.1)
        assert fmu.fn("DoStep") in text and "not allowed" in text
    elif case == "set_output":
        text = fmu.refused(fmu.set, "brake_demand", 0)
        assert fmu.fn("SetInteger" if fmi == 2 else "SetInt32") in text and "brake_demand" in text
        assert "output" in text
    elif case == "set_fixed_parameter":
        text = fmu.refused(fmu.set, "timeout_cycles", 5)
        assert fmu.fn("SetInteger" if fmi == 2 else "SetInt32") in text and "timeout_cycles" in text
        assert fmu.get("timeout_cycles") == 3  # a refused set has no effect
    elif case in ("step_zero", "step_negative"):
        # any positive step is accepted (issue 15); FMI 2.0 and 3.0 require communicationStepSize > 0
        h = 0.0 if case == "step_zero" else -0.1
        text = fmu.refused(fmu.slave.doStep, 0.1, h)
        assert fmu.fn("DoStep") in text and "communicationStepSize" in text and "> 0" in text
    elif case == "wrong_time":
        text = fmu.refused(fmu.slave.doStep, 0.5, 0.1)
        assert fmu.fn("DoStep") in text and "currentCommunicationPoint" in text
    elif case == "unknown_vr":
        text = fmu.refused(fmu.slave.getReal if fmi == 2 else fmu.slave.getFloat64, [9999])
        assert fmu.fn("GetReal" if fmi == 2 else "GetFloat64") in text and "9999" in text
    elif case == "wrong_type":
        getter = fmu.slave.getInteger if fmi == 2 else fmu.slave.getInt32
        text = fmu.refused(getter, [fmu.vr("ch1.distance")])
        assert fmu.fn("GetInteger" if fmi == 2 else "GetInt32") in text and "ch1.distance" in text
    assert [c for s, c, m in fmu.log if s == ERROR] == ["logError"]


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_same_calls_done_right_are_accepted(fmi, instance):
    """The counterpart of the refusals: a whole multiple of 0.1 s at the FMU's time, an
    input, a fixed parameter during initialisation and a typed get all succeed."""
    fmu = instance(("m1", fmi))
    fmu.enter_init()
    fmu.set("timeout_cycles", 5)
    fmu.slave.exitInitializationMode()
    fmu.set("ch1.distance", 12.5)
    fmu.step(0.1)
    fmu.step(0.3)
    fmu.step(0.2)
    assert fmu.get("cycle") == 6
    assert fmu.get("timeout_cycles") == 5 and fmu.get("ch1.distance") == 12.5
    assert [e for e in fmu.log if e[0] >= ERROR] == []


@pytest.mark.parametrize("fmi", [2, 3])
def test_after_an_error_only_reset_brings_the_instance_back(fmi, instance):
    """An error is final for the run: a correct doStep afterwards is refused as well;
    after fmiReset the instance initialises and steps again."""
    fmu = instance(("m1", fmi))
    fmu.init()
    fmu.refused(fmu.slave.doStep, 0.0, 0.0)
    text = fmu.refused(fmu.slave.doStep, 0.0, 0.1)
    assert fmu.fn("DoStep") in text and "not allowed" in text
    fmu.slave.reset()
    fmu.init()
    fmu.step(0.1)
    assert fmu.get("cycle") == 1


# ---- 5: bad parameters -------------------------------------------------------------------------

BAD_PARAMETERS = [
    ("topology", {"topology": 4}),
    ("timeout_cycles", {"timeout_cycles": 601}),                       # 601 x 100 ms > 60 s
    ("persistence_cycles", {"persistence_cycles": 1001}),
    ("emergency_decel_mms2", {"emergency_decel_mms2": 0}),
    ("service_decel_mms2", {"service_decel_mms2": 2300}),              # above band 2's 2200
    ("emergency_band2_cms", {"emergency_band2_cms": 12001}),
    ("emergency_band3_cms", {"emergency_band3_cms": 2000}),            # below band 2 (3000 cm/s)
    ("emergency_band2_mms2", {"emergency_band2_mms2": 0}),
    ("emergency_band2_mms2", {"emergency_band2_mms2": 2500}),          # rises above band 1's 2400 (issue 40)
    ("emergency_band3_mms2", {"emergency_band3_cms": 5000, "emergency_band3_mms2": 2300}),   # above band 2's 2200
    ("emergency_band3_mms2", {"emergency_band3_cms": 5000, "emergency_band3_mms2": 20001}),
    ("emergency_buildup_ms", {"emergency_buildup_ms": -1}),
    ("traction_cutoff_ms", {"traction_cutoff_ms": 30001}),
    ("max_accel_mms2", {"max_accel_mms2": 5001}),
    ("speed_error_permille", {"speed_error_permille": 501}),
    ("slippery_permille", {"slippery_permille": 1001}),
    ("degraded_permille", {"degraded_permille": 0}),
    ("max_gradient_permille", {"max_gradient_permille": 60, "slippery_permille": 300}),   # cannot stop downhill
    ("service_decel_mms2", {"service_decel_mms2": 300}),               # the service brake cannot stop downhill
    ("standstill_margin_dm", {"standstill_margin_dm": 10001}),
    ("warning_ms", {"warning_ms": -1}),
    ("emergency_release", {"emergency_release": 2}),
    ("release_confirm_cycles", {"release_confirm_cycles": 0}),
    ("safe_reaction", {"safe_reaction": 0}),
    ("max_overruns", {"max_overruns": 0}),
    ("distance_tolerance_dm", {"distance_tolerance_dm": 60001}),
    ("forget_ms", {"forget_ms": 0}),
    ("forget_ms", {"forget_ms": 600001}),
    ("sensor_range_dm", {"sensor_range_dm": 0}),
    ("sensor_range_dm", {"sensor_range_dm": 60001}),
]
BAD_IDS = [f"{name}-{'-'.join(f'{v}' for v in params.values())}" for name, params in BAD_PARAMETERS]


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name, params", BAD_PARAMETERS, ids=BAD_IDS)
def test_bad_parameters_are_refused_at_exit_initialization_like_the_python_core(name, params, fmi, instance):
    """fmiExitInitializationMode refuses the configuration with a message naming the
    parameter; the Python core refuses the same values naming the same parameter first."""
    fmu = instance(("m1", fmi))
    fmu.enter_init()
    for key, value in params.items():
        fmu.set(key, value)
    text = fmu.refused(fmu.slave.exitInitializationMode)
    assert fmu.fn("ExitInitializationMode") in text and f"{name} = {params[name]}:" in text
    with pytest.raises(ConfigurationError) as exc:
        check(config_from_parameters(params))
    assert str(exc.value).startswith(f"{name} = "), exc.value
    with pytest.raises(ConfigurationError, match=f"^{name} = "):
        MonitorReference(read("m1"), params)


VALID = {"topology": 2, "timeout_cycles": 5, "persistence_cycles": 7, "service_decel_mms2": 1200,
         "emergency_decel_mms2": 1200, "emergency_band2_cms": 0, "emergency_band2_mms2": -7, "safe_reaction": 1,
         "recovery_cycles": 1, "emergency_release": 0, "release_confirm_cycles": 1, "max_gradient_permille": 0,
         "warning_ms": 0, "speed_error_permille": 0, "emergency_buildup_ms": 0, "traction_cutoff_ms": 0}


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_valid_non_default_configuration_is_accepted_by_both_cores(fmi, instance):
    """The refusals above are about the values, not about setting parameters at all (an
    unused band's deceleration may be anything, as in Python); both cores then agree."""
    check(config_from_parameters(VALID))
    fmu = instance(("m1", fmi))
    fmu.init(VALID)
    fmu.step(0.1)
    assert fmu.get("topology") == 2 and fmu.get("cycle") == 1
    assert all(fmu.get(name) == value for name, value in VALID.items())


# ---- 5b: start values, and an FMU built from a braking declaration -----------------------------

def test_every_config_field_is_a_parameter_with_the_core_default():
    """Every Config field but period_ms (the constant output the table fixes) is an FMU
    parameter of the same name; its start value is Config()'s, and the reasons
    description lists the new bits."""
    params = {v.name: v for v in MONITOR if v.causality == "parameter"}
    assert set(params) == set(Config._fields) - {"period_ms"}
    for name, v in params.items():
        assert v.type == "Integer" and v.variability == "fixed" and v.description
        assert v.start == (3 if name == "topology" else getattr(Config(), name)), name
    reasons = next(v for v in MONITOR if v.name == "reasons").description
    assert "1024 sbi" in reasons and "2048 warning" in reasons and "4096 dispute" in reasons
    assert "8192 memory" in reasons
    assert next(v for v in MONITOR if v.name == "warning").type == "Boolean"


@pytest.mark.parametrize("key", MONITOR_KEYS, ids=_id)
def test_unset_parameters_start_at_the_core_defaults(key, instance):
    """An importer that sets nothing gets the values the model description states, which
    are the core's defaults, in C as well (rg_config_default and the generated starts)."""
    fmu = instance(key)
    fmu.init()
    for v in MONITOR:
        if v.causality == "parameter":
            assert fmu.get(v.name) == v.start, v.name


DECLARATION = """
[braking]
emergency_decel = [[0.0, 1.9], [25.0, 1.7], [40.0, 1.5]]
service_decel = 0.7
emergency_buildup_s = 1.6
service_buildup_s = 2.5
traction_cutoff_s = 1.1
max_accel = 0.8
speed_error = 0.03
slippery_factor = 0.6
degraded_factor = 0.75
max_downhill_gradient = 12
standstill_margin_m = 8.0
"""


@pytest.mark.parametrize("fmi", [2, 3])
def test_an_fmu_built_from_a_braking_declaration_starts_with_it(fmi, tmp_path):
    """build_monitor(config=...) with a declaration applied to the defaults: the model
    description's start values and the C start values are the declaration's, so an
    importer that sets no parameter runs it, and the FMU then equals the Python core
    under that configuration cycle for cycle."""
    from monitor import declaration

    path = tmp_path / "train.toml"
    path.write_text(DECLARATION)
    cfg = declaration.config_with(Config(), path)
    assert cfg.emergency_band3_cms == 4000 and cfg.emergency_buildup_ms == 1600
    fmu_path = build_monitor(read("m1"), fmi, tmp_path, config=cfg)
    md = read_model_description(str(fmu_path))
    starts = {v.name: v.start for v in md.modelVariables if v.causality == "parameter"}
    for name in cfg._fields:
        if name not in ("period_ms", "topology"):
            assert int(starts[name]) == getattr(cfg, name), name
    default = read_model_description(str(build_monitor(read("m1"), fmi, tmp_path / "default")))
    assert (md.guid if fmi == 2 else md.instantiationToken) != (default.guid if fmi == 2 else default.instantiationToken)
    driver = MonitorDriver(fmu_path)
    try:
        get = driver.slave.getInteger if fmi == 2 else driver.slave.getInt32
        for name in DECLARATION_FIELDS:
            assert get([vr_of(MONITOR, name)])[0] == getattr(cfg, name), name
        ref = MonitorReference(read("m1"), {}, base=cfg)
        for inp, cycles in _approach():
            driver.set(inp)
            assert driver.step(cycles) == tuple(ref.step(inp, cycles)[-1])
    finally:
        driver.close()


def test_build_refuses_a_configuration_the_core_refuses(tmp_path):
    """A declaration the core would refuse, or one for another cycle period than the
    table's, gives a BuildError naming the value, not an FMU that cannot initialise."""
    with pytest.raises(BuildError, match="service_decel_mms2 = 2300"):
        build_monitor(read("m1"), 2, tmp_path, config=Config(service_decel_mms2=2300))
    with pytest.raises(BuildError, match="period_ms = 200"):
        build_monitor(read("m1"), 2, tmp_path, config=Config(period_ms=200, timeout_cycles=3))


# ---- 6: NaN and out-of-range inputs ------------------------------------------------------------

HEALTHY = ChannelInput(status=1, distance=3000.0, closing_speed=20.0, type=0, valid=True)
GOOD = StepInput((HEALTHY,) * CHANNELS, speed=20.0)
BAD_CH3 = {
    "distance NaN": HEALTHY._replace(distance=math.nan),
    "distance +inf": HEALTHY._replace(distance=math.inf),
    "distance -1": HEALTHY._replace(distance=-1.0),
    "distance 6000.1": HEALTHY._replace(distance=6000.1),
    "closing 200": HEALTHY._replace(closing_speed=200.0),
    "status 5": HEALTHY._replace(status=5),
    "type 9": HEALTHY._replace(type=9),
}


def _normal_then(driver, model: str, inp: StepInput) -> dict:
    """Three healthy cycles (the monitor must be NORMAL, no demand), then one with `inp`;
    every output equals the Python reference's. The last outputs by name."""
    driver.reset()
    ref = MonitorReference(read(model))
    for _ in range(3):
        driver.set(GOOD)
        out = driver.step()
        assert out == tuple(ref.step(GOOD)[-1])
    before = dict(zip(OUT_NAMES, out))
    assert before["mode"] == NORMAL and not before["system_error"] and before["brake_demand"] == 0
    assert before["reasons"] & R_STALE == 0
    driver.set(inp)
    out = driver.step()
    assert out == tuple(ref.step(inp)[-1])
    return dict(zip(OUT_NAMES, out))


@pytest.mark.parametrize("key", MONITOR_KEYS, ids=_id)
@pytest.mark.parametrize("bad", list(BAD_CH3), ids=list(BAD_CH3))
def test_a_bad_channel_value_counts_as_degraded(bad, key, monitor_drivers):
    """One bad value on channel 3 makes it DEGRADED: system error, reason 'stale', the flag
    of module 2 (channels 3-4) and the safe reaction (emergency), as in the Python core."""
    chans = list(GOOD.channels)
    chans[2] = BAD_CH3[bad]
    out = _normal_then(monitor_drivers[key], key[0], GOOD._replace(channels=tuple(chans)))
    assert out["system_error"] is True
    assert out["reasons"] & R_STALE
    assert out["module_flags"] == 0b010  # module 2 only
    assert out["mode"] == DEGRADED
    assert out["brake_demand"] == 2


@pytest.mark.parametrize("key", MONITOR_KEYS, ids=_id)
def test_a_nan_train_speed_is_a_train_input_error(key, monitor_drivers):
    """NaN train.speed: reason bit train_input, system error, emergency demand, while the
    channels stay healthy (no module flag, not stale)."""
    out = _normal_then(monitor_drivers[key], key[0], GOOD._replace(speed=math.nan))
    assert out["reasons"] & R_TRAIN_INPUT and out["system_error"] is True
    assert out["brake_demand"] == 2
    assert out["module_flags"] == 0 and out["reasons"] & R_STALE == 0


# ---- 7: the table integrity check in C ---------------------------------------------------------

TABLE_CHECK_C = r"""
#include <stdio.h>
#include "rg_core.h"
#include "rg_table.h"

int main(void)
{
    rg_table t;
    rg_config c;
    char msg[256] = "";
    int rc;
    rg_config_default(&c);
    t.bytes = RG_TABLE_BYTES;
    t.length = RG_TABLE_LENGTH;
    t.action_offset = RG_TABLE_ACTION_OFFSET;
    t.next_offset = RG_TABLE_NEXT_OFFSET;
    t.risk_offset = RG_TABLE_RISK_OFFSET;
    t.nodes = RG_TABLE_NODES;
    t.observations = RG_TABLE_OBSERVATIONS;
    t.index_bytes = RG_TABLE_INDEX_BYTES;
    t.start = RG_TABLE_START;
    t.model = RG_TABLE_MODEL;
    t.period_ms = RG_TABLE_PERIOD_MS;
    rc = rg_table_check(&t, &c, msg, sizeof msg);
    printf("%d\n%s\n", rc, msg);
    return 0;
}
"""

SHA256_C = r"""
#include <stdio.h>
#include "rg_sha256.h"

static unsigned char data[1 << 16];

int main(int argc, char **argv)
{
    FILE *f;
    size_t n, i;
    uint8_t digest[32];
    if (argc != 2 || (f = fopen(argv[1], "rb")) == NULL) return 2;
    n = fread(data, 1, sizeof data, f);
    fclose(f);
    rg_sha256(data, n, digest);
    for (i = 0; i < 32; i++) printf("%02x", digest[i]);
    printf("\n");
    return 0;
}
"""


def _compile(folder: Path, main: str, extra_includes=()) -> Path:
    (folder / "main.c").write_text(main)
    exe = folder / "main"
    core = C_DIR / "core"
    cmd = [compiler(), *[f for f in CFLAGS if f != "-fPIC"], f"-I{folder}", f"-I{core}",
           *(f"-I{d}" for d in extra_includes), str(folder / "main.c"), str(core / "rg_core.c"),
           str(core / "rg_sha256.c"), "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return exe


def _table_check(folder: Path, layout_bytes: bytes, data: bytes) -> tuple[int, str]:
    folder.mkdir()
    (folder / "rg_table.h").write_text(generate.table_header(decode(layout_bytes), data))
    out = subprocess.run([str(_compile(folder, TABLE_CHECK_C))], capture_output=True, text=True, check=True)
    rc, msg = out.stdout.split("\n", 1)
    return int(rc), msg.strip()


@pytest.mark.parametrize("model", ["m1", "m2"])
def test_c_table_check_passes_the_shipped_table_and_refuses_one_flipped_byte(model, tmp_path):
    """rg_table_check accepts the table as shipped; one flipped bit in the JSON header,
    in the next-node body or in the stored digest is refused with a SHA-256 message."""
    good = read(model)
    assert _table_check(tmp_path / "good", good, good) == (0, "")
    for where, at in (("header", 20), ("body", len(good) - 40), ("digest", len(good) - 1)):
        bad = bytearray(good)
        bad[at] ^= 0x01
        rc, msg = _table_check(tmp_path / where, good, bytes(bad))
        assert rc != 0 and "SHA-256" in msg and msg.startswith("table refused"), (where, msg)


def test_c_sha256_equals_hashlib_around_the_block_boundaries(tmp_path):
    """rg_sha256, on which the table check rests, equals hashlib's SHA-256 for lengths on
    both sides of the 55/56-byte padding split and the 64-byte block."""
    exe = _compile(tmp_path, SHA256_C)
    rng = random.Random(5)
    for n in (0, 1, 55, 56, 63, 64, 65, 119, 120, 128, 1000):
        data = bytes(rng.randrange(256) for _ in range(n))
        (tmp_path / "in.bin").write_bytes(data)
        out = subprocess.run([str(exe), str(tmp_path / "in.bin")], capture_output=True, text=True, check=True)
        assert out.stdout.strip() == hashlib.sha256(data).hexdigest(), n


# ---- 8: the train FMU ----------------------------------------------------------------------------

def test_train_cruises_at_its_initial_speed_without_a_demand(instance):
    """Default parameters, brake_demand 0 with the monitor alive (its cycle counter moving):
    speed stays 20 m/s, the train covers 20 m per second, no brake level, no collision (the
    obstacle is 500 m ahead)."""
    fmu = instance("train")
    fmu.init({"brake_demand": 0})
    for k in range(1, 51):
        fmu.set("monitor_cycle", k)
        fmu.step(0.1)
        assert fmu.get("train.speed") == pytest.approx(20.0, abs=1e-9)
        assert fmu.get("position") == pytest.approx(2.0 * k, rel=1e-9)
    assert fmu.get("brake_level") == 0 and fmu.get("collided") is False
    assert fmu.get("true_distance") == pytest.approx(400.0, rel=1e-9)


def test_train_brake_receiver_holds_an_unknown_level_or_a_stopped_counter_to_standstill(instance):
    """Issue 39 item 3: a demand no monitor sends (7), for one monitor period, raises the
    receiver's emergency and it is held to standstill though "none" follows with the counter
    moving; a counter that stops moving (the monitor gone) does the same 0.3 s later."""
    for fault in ("level", "counter"):
        fmu = instance("train")
        fmu.init({"brake_demand": 0, "obstacle.present": False})
        speeds = []
        for k in range(1, 401):                                   # 40 s of 0.1 s steps
            bad = fault == "level" and k == 30
            fmu.set("brake_demand", 7 if bad else 0)
            fmu.set("monitor_cycle", k if fault == "level" or k < 30 else 30)
            fmu.step(0.1)
            speeds.append(fmu.get("true_speed"))
        assert speeds[28] == pytest.approx(20.0)                  # cruising before
        assert fmu.get("true_speed") == 0.0, fault               # held to standstill
        assert all(b <= a for a, b in zip(speeds[30:], speeds[31:])), fault    # never released under way


def test_train_stops_on_emergency_demand(instance):
    """brake_demand 2 (obeyed from t = 1 s, the hand-over) brings the train to a standstill
    well before the obstacle, slowing monotonically, and it stays there."""
    fmu = instance("train")
    fmu.init({"brake_demand": 2})
    speeds = []
    for _ in range(150):
        fmu.step(0.1)
        speeds.append(fmu.get("train.speed"))
    assert speeds[9] == pytest.approx(20.0)           # t = 1.0 s: hand-over, not braking yet
    assert all(b <= a for a, b in zip(speeds, speeds[1:]))
    assert speeds[-1] == 0.0 and speeds[-20:] == [0.0] * 20
    assert fmu.get("brake_level") == 2 and fmu.get("collided") is False
    assert 50.0 < fmu.get("position") < 150.0


@pytest.mark.parametrize("name, value", [("mass", 0.0), ("fault.kind", 9), ("gradient", 100.0)])
def test_train_refuses_bad_parameters_at_exit_initialization(name, value, instance):
    """A parameter out of its range is refused at fmi2ExitInitializationMode with a
    message naming it."""
    fmu = instance("train")
    fmu.enter_init()
    fmu.set(name, value)
    text = fmu.refused(fmu.slave.exitInitializationMode)
    assert "fmi2ExitInitializationMode" in text and f"{name} = " in text


def _distances(instance, seed: int) -> list:
    fmu = instance("train")
    fmu.init({"sensor.seed": seed, "obstacle.position": 300.0})
    rows = []
    for _ in range(20):
        fmu.step(0.1)
        rows.append(tuple(fmu.get(f"ch{i}.distance") for i in range(1, CHANNELS + 1)))
    assert all(fmu.get(f"ch{i}.status") == 1 for i in range(1, CHANNELS + 1))
    assert len({d for row in rows for d in row}) > 100  # noisy: the values differ
    return rows


def test_train_sensor_noise_repeats_for_a_seed(instance):
    """The same sensor.seed gives the same channel distances bit for bit; another seed
    gives other ones."""
    first = _distances(instance, 7)
    assert _distances(instance, 7) == first
    assert _distances(instance, 8) != first


@pytest.mark.parametrize("key", MONITOR_KEYS, ids=_id)
def test_the_monitor_binary_needs_nothing_from_libm(key, monitor_fmus, tmp_path):
    """FMI 2.0 cannot declare a library dependency and FMPy's CMake build links no -lm: a
    monitor rebuilt from its sources must load anywhere, so it imports no libm symbol."""
    import zipfile

    with zipfile.ZipFile(monitor_fmus[key]) as zf:
        name = next(n for n in zf.namelist() if n.startswith("binaries/") and n.endswith(".so"))
        binary = tmp_path / "monitor.so"
        binary.write_bytes(zf.read(name))
    listing = subprocess.run(["nm", "-D", "--undefined-only", str(binary)], capture_output=True, text=True,
                             check=True).stdout.split()
    undefined = {word.split("@")[0] for word in listing}
    libm = {"floor", "ceil", "lround", "round", "fmax", "fmin", "fabs", "sqrt", "pow", "exp", "log", "trunc"}
    assert not libm & undefined, sorted(libm & undefined)
    assert "snprintf" in undefined        # the listing is real: libc symbols are imported
