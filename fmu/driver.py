"""Drive an FMU from Python through FMPy with little overhead: value-reference arrays are
prepared once and the FMI functions FMPy bound from the binary are called directly.

`Port` is one prepared get or set of one type; `open_slave` instantiates an FMI 2 or 3
Co-Simulation FMU with FMPy's slave classes; `MonitorDriver` steps the monitor FMU with
the same inputs as fmu.reference.MonitorReference, for tests and for HIL-style scripts.
"""
from __future__ import annotations

import ctypes
import shutil
import sys
import zipfile
from pathlib import Path

from fmpy import calloc, free

from .variables import CHANNELS, MONITOR, MONITOR_OUTPUTS

_TYPE_NAMES = {2: {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean"},
               3: {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}}


class FmuCallError(RuntimeError):
    """An FMI function returned Error or Fatal."""


def vr_of(variables, name: str) -> int:
    for i, v in enumerate(variables):
        if v.name == name:
            return i
    raise KeyError(f"no variable {name!r}")


def raw_function(dll, name: str):
    """A fresh ctypes function pointer to `name` (returns int, no argument conversion)."""
    func = dll._FuncPtr((name, dll))
    func.restype = ctypes.c_int
    return func


class Port:
    """A prepared fmiGet*/fmiSet* call of one type over fixed value references."""

    def __init__(self, slave, fmi: int, kind: str, vrs: list[int], direction: str):
        self.n = len(vrs)
        self.vrs = (ctypes.c_uint32 * self.n)(*vrs)
        ctype = {"Real": ctypes.c_double, "Integer": ctypes.c_int32,
                 "Boolean": ctypes.c_int32 if fmi == 2 else ctypes.c_bool}[kind]
        self.values = (ctype * self.n)()
        self.fname = f"fmi{fmi}{'Get' if direction == 'get' else 'Set'}{_TYPE_NAMES[fmi][kind]}"
        # a function pointer of our own, without FMPy's argtypes: the arguments are built as
        # ctypes objects once here, so a call converts nothing
        self.func = raw_function(slave.dll, self.fname)
        count = ctypes.c_size_t(self.n)
        self.args = ((ctypes.c_void_p(slave.component), self.vrs, count, self.values) if fmi == 2
                     else (ctypes.c_void_p(slave.component), self.vrs, count, self.values, count))
        self.fmi = fmi

    def call(self) -> None:
        status = self.func(*self.args)
        if status > 1:
            raise FmuCallError(f"{self.fname} returned status {status}")

    def copy_from(self, other: "Port") -> None:
        """Take the values of another port of the same length (FMI 2 and 3 Booleans differ in size)."""
        if ctypes.sizeof(self.values) == ctypes.sizeof(other.values):
            ctypes.memmove(self.values, other.values, ctypes.sizeof(self.values))
        else:
            for i in range(self.n):
                self.values[i] = bool(other.values[i])


LOG_LABELS = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")


def _log_to_stderr(instance: str):
    """An FMU log callback that writes to stderr (FMPy's default prints on stdout, which
    would corrupt a command's --json output)."""
    def log(status: int, message) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        label = LOG_LABELS[status] if 0 <= status < len(LOG_LABELS) else str(status)
        print(f"[{label}] {instance}: {text}", file=sys.stderr, flush=True)

    return log


def _fmi2_callbacks(instance: str):
    from ctypes import byref

    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                           fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy

    log = _log_to_stderr(instance)
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda component, name, status, category, message: log(status, message))
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(byref(callbacks))
    return callbacks


def check_fmu_file(path: str | Path) -> None:
    """A readable .fmu (a zip archive), or one line naming the file."""
    p = Path(path)
    if not p.is_file():
        raise FmuFileError(f"{p}: no such FMU file")
    if not zipfile.is_zipfile(p):
        raise FmuFileError(f"{p}: not an FMU (an FMU is a zip archive with a modelDescription.xml)")


class FmuFileError(ValueError):
    """A file given as an FMU that is not one; the message names it."""


def open_slave(path: str | Path, name: str):
    """(slave, fmi version, unzip dir) of an instantiated FMU; the caller frees it with
    close_slave. The FMU's log messages go to stderr."""
    from fmpy import extract, read_model_description

    check_fmu_file(path)
    try:
        md = read_model_description(str(path))
    except Exception as exc:  # noqa: BLE001 - FMPy raises many kinds for a broken archive
        raise FmuFileError(f"{path}: not a readable FMU: {str(exc).strip() or type(exc).__name__}") from None
    fmi = 3 if md.fmiVersion.startswith("3") else 2
    unzip = extract(str(path))
    kwargs = dict(unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    if fmi == 2:
        from fmpy.fmi2 import FMU2Slave

        slave = FMU2Slave(guid=md.guid, **kwargs)
        slave.instantiate(callbacks=_fmi2_callbacks(name))
    else:
        from fmpy.fmi3 import FMU3Slave

        slave = FMU3Slave(guid=md.instantiationToken, **kwargs)
        log = _log_to_stderr(name)
        slave.instantiate(logMessage=lambda env, status, category, message: log(status, message))
    return slave, fmi, unzip


def close_slave(slave, unzip) -> None:
    for call in (slave.terminate, slave.freeInstance):
        try:
            call()
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass
    shutil.rmtree(unzip, ignore_errors=True)


def set_values(slave, fmi: int, variables, values: dict) -> None:
    """Set variables by name through FMPy's ordinary calls (initialisation, parameters)."""
    for key, value in values.items():
        vr = [vr_of(variables, key)]
        kind = variables[vr[0]].type
        if kind == "Real":
            (slave.setReal if fmi == 2 else slave.setFloat64)(vr, [float(value)])
        elif kind == "Integer":
            (slave.setInteger if fmi == 2 else slave.setInt32)(vr, [int(value)])
        else:
            slave.setBoolean(vr, [bool(value)])


def initialize(slave, fmi: int, variables, params: dict, start: float = 0.0) -> None:
    if fmi == 2:
        slave.setupExperiment(startTime=start)
        slave.enterInitializationMode()
    else:
        slave.enterInitializationMode(startTime=start)
    set_values(slave, fmi, variables, params)
    slave.exitInitializationMode()


def do_step_function(slave, fmi: int):
    """f(t, h) -> status, calling fmiDoStep directly."""
    step = raw_function(slave.dll, f"fmi{fmi}DoStep")
    c = ctypes.c_void_p(slave.component)
    double = ctypes.c_double
    if fmi == 2:
        yes = ctypes.c_int(1)
        return lambda t, h: step(c, double(t), double(h), yes)
    flags = [ctypes.c_bool() for _ in range(3)]
    last = ctypes.c_double()
    refs = [ctypes.byref(f) for f in flags] + [ctypes.byref(last)]
    yes = ctypes.c_bool(True)
    return lambda t, h: step(c, double(t), double(h), yes, *refs)


class MonitorDriver:
    """The monitor FMU stepped from Python: set(StepInput), step(cycles) -> output tuple in
    the order of fmu.variables.MONITOR_OUTPUTS (the fields of monitor.core.types.Outputs)."""

    def __init__(self, path: str | Path, params: dict | None = None):
        self.slave, self.fmi, self.unzip = open_slave(path, "monitor")
        initialize(self.slave, self.fmi, MONITOR, params or {})
        names = [v.name for v in MONITOR_OUTPUTS]
        bools = [v.name for v in MONITOR_OUTPUTS if v.type == "Boolean"]
        self.int_out = Port(self.slave, self.fmi, "Integer", [vr_of(MONITOR, n) for n in names if n not in bools], "get")
        self.bool_out = Port(self.slave, self.fmi, "Boolean", [vr_of(MONITOR, n) for n in bools], "get")
        ch = range(1, CHANNELS + 1)
        self.reals = Port(self.slave, self.fmi, "Real", [vr_of(MONITOR, f"ch{i}.{f}") for i in ch
                                                         for f in ("distance", "closing_speed")] + [vr_of(MONITOR, "train.speed")], "set")
        self.ints = Port(self.slave, self.fmi, "Integer", [vr_of(MONITOR, f"ch{i}.{f}") for i in ch for f in ("status", "type")]
                         + [vr_of(MONITOR, "train.track_condition"), vr_of(MONITOR, "train.brake_status")], "set")
        self.bools = Port(self.slave, self.fmi, "Boolean", [vr_of(MONITOR, f"ch{i}.valid") for i in ch], "set")
        self._step = do_step_function(self.slave, self.fmi)
        self._bool_index = [names.index(n) for n in bools]    # ascending
        self.time = 0.0
        self.steps = 0

    def reset(self, params: dict | None = None) -> None:
        """Back to the start (fmiReset) and initialise again with `params`: a new run
        without extracting and loading the FMU again."""
        self.slave.reset()
        initialize(self.slave, self.fmi, MONITOR, params or {})
        self.time = 0.0
        self.steps = 0

    def set(self, inp) -> None:
        """Inputs of one communication step (an fmu.reference.StepInput)."""
        r, n, b = self.reals.values, self.ints.values, self.bools.values
        for i, ch in enumerate(inp.channels):
            r[2 * i], r[2 * i + 1] = ch.distance, ch.closing_speed
            n[2 * i], n[2 * i + 1] = ch.status, ch.type
            b[i] = bool(ch.valid)
        r[2 * CHANNELS] = inp.speed
        n[2 * CHANNELS], n[2 * CHANNELS + 1] = inp.track, inp.brake
        self.reals.call()
        self.ints.call()
        self.bools.call()

    def step(self, cycles: int = 1) -> tuple:
        h = 0.1 * cycles
        status = self._step(self.time, h)
        if status > 1:
            raise FmuCallError(f"fmi{self.fmi}DoStep at t = {self.time} returned status {status}")
        self.steps += cycles
        self.time = round(self.steps * 0.1, 9)
        self.int_out.call()
        self.bool_out.call()
        values = list(self.int_out.values)
        for k, at in enumerate(self._bool_index):
            values.insert(at, bool(self.bool_out.values[k]))
        return tuple(values)

    def close(self) -> None:
        close_slave(self.slave, self.unzip)
