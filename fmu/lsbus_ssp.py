"""The CAN network system as an SSP (System Structure and Parameterization 1.0) file: the
bus simulation FMU and the node FMUs as components, each node's terminal wired to the bus's
Node{k} terminal variable by variable (Tx_Data -> Rx_Data and Tx_Clock -> Rx_Clock, both
ways), the run's parameters as a parameter binding, and the outputs the container exposes as
system connectors. fmu-manipulation-toolbox's fmucontainer reads it (`fmucontainer -container
system.ssp -fmi 3`), so the SSP describes the very system `railguard cosim --bus ls-bus` runs.
Connector types are left to the components (SSP 1.0 has no clock type)."""
from __future__ import annotations

import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .ssp import SSD_NS, _parameter

MEMBERS = ("Rx_Clock", "Rx_Data", "Tx_Clock", "Tx_Data")


def _component(name: str, source: str, connectors: list[tuple[str, str]]) -> str:
    rows = "".join(f'          <ssd:Connector name={quoteattr(c)} kind="{kind}"/>\n' for c, kind in connectors)
    return (f'      <ssd:Component name={quoteattr(name)} type="application/x-fmu-sharedlibrary" '
            f'source="resources/{source}">\n        <ssd:Connectors>\n{rows}        </ssd:Connectors>\n'
            "      </ssd:Component>\n")


def _terminal(network: str) -> list[tuple[str, str]]:
    return [(f"{network}.{m}", "input" if m.startswith("Rx") else "output") for m in MEMBERS]


def system_structure(bus: str, nodes: list[tuple[str, str, str]], parameters: dict, outputs: list) -> str:
    """`bus`: the bus FMU's component name; `nodes`: (component, FMU file, terminal name);
    `parameters`: {(component, variable): value}; `outputs`: (component, variable, system
    connector)."""
    wires = []
    for k, (name, _, term) in enumerate(nodes, 1):
        wires += [(name, f"{term}.Tx_Data", bus, f"Node{k}.Rx_Data"), (name, f"{term}.Tx_Clock", bus, f"Node{k}.Rx_Clock"),
                  (bus, f"Node{k}.Tx_Data", name, f"{term}.Rx_Data"), (bus, f"Node{k}.Tx_Clock", name, f"{term}.Rx_Clock")]
    by_component: dict = {}
    for comp, var, _ in outputs:
        by_component.setdefault(comp, []).append((var, "output"))
    bus_connectors = [c for k in range(1, len(nodes) + 1) for c in _terminal(f"Node{k}")] + by_component.get(bus, [])
    elements = _component(bus, f"{bus}.fmu", bus_connectors)
    for name, fmu, term in nodes:
        elements += _component(name, fmu, _terminal(term) + by_component.get(name, []))
    conns = "".join(f'      <ssd:Connection startElement="{a}" startConnector={quoteattr(b)} endElement="{c}" '
                    f'endConnector={quoteattr(d)}/>\n' for a, b, c, d in wires)
    conns += "".join(f'      <ssd:Connection startElement="{comp}" startConnector={quoteattr(var)} '
                     f'endConnector={quoteattr(out)}/>\n' for comp, var, out in outputs)
    system_connectors = "".join(f'      <ssd:Connector name={quoteattr(out)} kind="output"/>\n' for _, _, out in outputs)
    params = "".join(_parameter(f"{comp}.{var}", value) for (comp, var), value in parameters.items()
                     if not isinstance(value, str))
    bindings = ("    <ssd:ParameterBindings>\n      <ssd:ParameterBinding>\n        <ssd:ParameterValues>\n"
                f'          <ssv:ParameterSet version="1.0" name="run">\n            <ssv:Parameters>\n{params}'
                "            </ssv:Parameters>\n          </ssv:ParameterSet>\n"
                "        </ssd:ParameterValues>\n      </ssd:ParameterBinding>\n    </ssd:ParameterBindings>\n"
                if params else "")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<ssd:SystemStructureDescription {SSD_NS} version="1.0" name="railguard-can">\n'
            '  <ssd:System name="railguard_can" description="railguard nodes on a simulated CAN bus (FMI-LS-BUS)">\n'
            + (f"    <ssd:Connectors>\n{system_connectors}    </ssd:Connectors>\n" if outputs else "")
            + bindings + f"    <ssd:Elements>\n{elements}    </ssd:Elements>\n"
            + f"    <ssd:Connections>\n{conns}    </ssd:Connections>\n  </ssd:System>\n"
            + "</ssd:SystemStructureDescription>\n")


def write(path: Path, bus_fmu: Path, nodes: list[tuple[str, Path, str]], parameters: dict, outputs: list) -> Path:
    """The .ssp archive: SystemStructure.ssd and the FMUs under resources/."""
    bus = bus_fmu.stem
    ssd = system_structure(bus, [(n, p.name, t) for n, p, t in nodes], parameters, outputs)
    path = Path(path)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for fmu in [bus_fmu] + [p for _, p, _ in nodes]:
            zf.write(fmu, f"resources/{fmu.name}")
    return path
