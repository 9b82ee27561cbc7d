"""The closed loop as an SSP (System Structure and Parameterization 1.0) file: the train
FMU and the monitor FMU, every connection between them, and the scenario's parameters as a
parameter binding. FMPy's SSP runner simulates it (fmpy.ssp.simulate_ssp), so the same
loop runs in any SSP-capable tool. FMPy's runner steps both FMUs with one step size and
hands outputs over after the step (each input lags one step), so the step is the
monitor's 100 ms period.
"""
from __future__ import annotations

import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .variables import CHANNELS, MONITOR, TRAIN

SSD_NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
          'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"')
STEP_S = 0.1

# (train output, monitor input): every sensor channel and the train state; plus the demand back
LINKS = ([(f"ch{i}.{f}", f"ch{i}.{f}") for i in range(1, CHANNELS + 1)
          for f in ("status", "distance", "closing_speed", "type", "valid")]
         + [("train.speed", "train.speed"), ("train.track_condition", "train.track_condition"),
            ("train.brake_status", "train.brake_status")])
# (monitor output, train input): the demand back, with the monitor's alive counter for the
# train's brake receiver (issue 39: a monitor that stops brakes the train)
FEEDBACK = (("brake_demand", "brake_demand"), ("cycle", "monitor_cycle"))
RECORDED = ["train.speed", "position", "true_distance", "brake_level", "collided"]


def _type(variables, name: str) -> str:
    return next(v.type for v in variables if v.name == name)


def _connector(name: str, kind: str, type_: str) -> str:
    return f'        <ssd:Connector name={quoteattr(name)} kind="{kind}"><ssc:{type_}/></ssd:Connector>\n'


def _parameter(name: str, value) -> str:
    if isinstance(value, bool):
        inner = f'<ssv:Boolean value="{"true" if value else "false"}"/>'
    elif isinstance(value, int):
        inner = f'<ssv:Integer value="{value}"/>'
    else:
        inner = f'<ssv:Real value="{float(value)!r}"/>'
    return f"              <ssv:Parameter name={quoteattr(name)}>{inner}</ssv:Parameter>\n"


def system_structure(train_source: str, monitor_source: str, train_params: dict, monitor_params: dict,
                     stop_time: float, name: str) -> str:
    train_out = {a for a, _ in LINKS} | set(RECORDED)
    tc = "".join(_connector(n, "output", _type(TRAIN, n)) for n in sorted(train_out))
    tc += "".join(_connector(b, "input", "Integer") for _, b in FEEDBACK)
    mc = "".join(_connector(b, "input", _type(MONITOR, b)) for _, b in LINKS)
    mc += "".join(_connector(n, "output", _type(MONITOR, n))
                  for n in ("brake_demand", "cycle", "mode", "reasons", "voted_distance_dm"))
    conns = "".join(f'      <ssd:Connection startElement="train" startConnector={quoteattr(a)} endElement="monitor" '
                    f'endConnector={quoteattr(b)}/>\n' for a, b in LINKS)
    conns += "".join(f'      <ssd:Connection startElement="monitor" startConnector="{a}" endElement="train" '
                     f'endConnector="{b}"/>\n' for a, b in FEEDBACK)
    params = "".join(_parameter(f"train.{k}", v) for k, v in train_params.items())
    params += "".join(_parameter(f"monitor.{k}", v) for k, v in monitor_params.items())
    bindings = ""
    if params:
        bindings = ("    <ssd:ParameterBindings>\n      <ssd:ParameterBinding>\n        <ssd:ParameterValues>\n"
                    f'          <ssv:ParameterSet version="1.0" name="scenario">\n            <ssv:Parameters>\n{params}'
                    "            </ssv:Parameters>\n          </ssv:ParameterSet>\n"
                    "        </ssd:ParameterValues>\n      </ssd:ParameterBinding>\n    </ssd:ParameterBindings>\n")
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<ssd:SystemStructureDescription {SSD_NS} version="1.0" name={quoteattr(name)}>\n'
        '  <ssd:System name="closed_loop" description="railguard monitor FMU braking the train-dynamics FMU">\n'
        + bindings
        + "    <ssd:Elements>\n"
        f'      <ssd:Component name="train" type="application/x-fmu-sharedlibrary" source="{train_source}">\n'
        f"      <ssd:Connectors>\n{tc}      </ssd:Connectors>\n      </ssd:Component>\n"
        f'      <ssd:Component name="monitor" type="application/x-fmu-sharedlibrary" source="{monitor_source}">\n'
        f"      <ssd:Connectors>\n{mc}      </ssd:Connectors>\n      </ssd:Component>\n"
        "    </ssd:Elements>\n"
        f"    <ssd:Connections>\n{conns}    </ssd:Connections>\n"
        "  </ssd:System>\n"
        f'  <ssd:DefaultExperiment startTime="0.0" stopTime="{stop_time}"/>\n'
        "</ssd:SystemStructureDescription>\n"
    )


def write(path: str | Path, train_fmu: str | Path, monitor_fmu: str | Path, train_params: dict,
          monitor_params: dict, stop_time: float, name: str = "railguard-closed-loop") -> Path:
    """An .ssp archive holding SystemStructure.ssd and both FMUs under resources/."""
    train_src, monitor_src = f"resources/{Path(train_fmu).name}", f"resources/{Path(monitor_fmu).name}"
    ssd = system_structure(train_src, monitor_src, train_params, monitor_params, stop_time, name)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        zf.write(train_fmu, train_src)
        zf.write(monitor_fmu, monitor_src)
    return out


def simulate(path: str | Path, stop_time: float | None = None):
    """Run the SSP with FMPy's SSP runner and its own parameter binding; returns FMPy's
    structured array (columns named component.connector)."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import read_ssd

    ssd = read_ssd(str(path))
    bindings = ssd.system.parameterBindings
    parameter_set = bindings[0].parameterValues[0] if bindings and bindings[0].parameterValues else None
    stop = stop_time if stop_time is not None else float(_default_stop(path))
    return simulate_ssp(str(path), stop_time=stop, step_size=STEP_S, parameter_set=parameter_set)


def _default_stop(path) -> float:
    import re

    with zipfile.ZipFile(path) as zf:
        text = zf.read("SystemStructure.ssd").decode()
    m = re.search(r'<ssd:DefaultExperiment[^>]*stopTime="([^"]+)"', text)
    return float(m.group(1)) if m else 60.0
