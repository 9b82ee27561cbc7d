"""The train as a network FMU (issue 42): the train-dynamics model of the signal
co-simulation (fmu/c/train/model.c, unchanged, through its model.h contract) behind an
FMI-LS-BUS CAN terminal and the C frame layer, so that `railguard cosim` can run over the
simulated bus: TrainState and the six ObstacleReports out at every monitor instant, the
monitor's BrakeDemand in (fmu/c/lsbus/train_node/config.h says when and how).

Staging: the train model's config.h, variables.h and model.h would collide with the network
node's config.h in the one flat sources folder, so they are staged under prefixed names
(train_config.h, train_variables.h, train_model.h, train_model.c) with their #include lines
rewritten; the node's adapter reads the model's value references from train_vr.h (tvr_*, so
they do not meet the node's own vr_* names) and its parameters from train_params.h, both
generated from fmu/variables.py's TRAIN. fmu/c/train stays as it is.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Optional

from . import generate
from .build import C_DIR, BuildError
from .lsbus_system import BIT_RATE
from .network_build import NetVar, NetworkFmu, build, terminal
from .network_nodes import FRAME_LAYER, dbc_sources, keys_blob
from .variables import TRAIN

TRAIN_NODE_ID = "railguard_train_can"
_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
_C_TYPES = {"Real": "RG_NT_FLOAT64", "Integer": "RG_NT_INT32", "Boolean": "RG_NT_BOOLEAN"}
# the train model's files as staged: the name in the folder -> (source, its includes renamed)
_RENAMES = {"model.h": "train_model.h", "variables.h": "train_variables.h", "config.h": "train_config.h"}
PARAMETERS = [v for v in TRAIN if v.causality == "parameter"]
OUTPUTS = [
    NetVar("position", "Float64", "output", "train position (m)"),
    NetVar("true_speed", "Float64", "output", "train speed (m/s)"),
    NetVar("train.speed", "Float64", "output", "train speed as reported in TrainState (m/s)"),
    NetVar("acceleration", "Float64", "output", "train acceleration (m/s2)"),
    NetVar("true_distance", "Float64", "output", "true distance to the obstacle (m; 1e9 without one)"),
    NetVar("brake_decel", "Float64", "output", "brake deceleration acting now (m/s2)"),
    NetVar("impact_speed", "Float64", "output", "our speed when train and obstacle met (m/s)"),
    NetVar("brake_level", "Int32", "output", "brake level in effect after the brake delay"),
    NetVar("applied_demand", "Int32", "output", "the demand the model reads: the newest accepted BrakeDemand's Level"),
    NetVar("applied_cycle", "Int32", "output", "the alive counter the model reads: that frame's Cycle"),
    NetVar("frames_rx", "Int32", "output", "frames received"),
    NetVar("frames_rejected", "Int32", "output", "frames refused (E2E, SecOC, frame kind)"),
    NetVar("frames_tx", "Int32", "output", "frames sent"),
    NetVar("demand_frames", "Int32", "output", "BrakeDemand frames accepted"),
    NetVar("last_demand_time", "Float64", "output", "arrival of the newest accepted BrakeDemand (-1: none)", unit="s"),
    NetVar("receiver_brake_time", "Float64", "output",
           "when the model's alive timeout first braked (its 10 ms grid instant; -1: never)", unit="s"),
    NetVar("collided", "Boolean", "output", "train and obstacle met (see impact_speed)"),
    NetVar("receiver_brake", "Boolean", "output", "the alive timeout holds an emergency: BrakeDemand's Cycle stopped"),
    NetVar("secured", "Boolean", "output", "the node holds a key set: secured CAN FD frames"),
]


def _rename_includes(text: str, what: str) -> str:
    """`text` with its #include "X" lines for the train model's headers renamed; every
    staged file must still include what it did, so an upstream change fails here."""
    def sub(match):
        return f'#include "{_RENAMES[match.group(1)]}"'
    out, n = re.subn(r'#include "(model\.h|variables\.h|config\.h)"', sub, text)
    if n == 0:
        raise BuildError(f"staging the train model: {what} includes none of {sorted(_RENAMES)}")
    return out


def staged_train_model() -> tuple:
    """(name, text) of the train model's files under their prefixed names."""
    return (("train_config.h", (C_DIR / "train" / "config.h").read_text()),
            ("train_model.h", _rename_includes((C_DIR / "fmi" / "model.h").read_text(), "fmi/model.h")),
            ("train_model.c", _rename_includes((C_DIR / "train" / "model.c").read_text(), "train/model.c")),
            ("train_variables.h", _rename_includes(generate.variables_header(TRAIN), "variables.h")))


def _c_number(name: str, value) -> str:
    v = float(value)
    if not math.isfinite(v):
        raise BuildError(f"train parameter {name} = {value!r}: must be finite")
    return repr(v)


def params_header(starts: dict) -> str:
    """train_vr.h's tvr_* (the model's value references) and train_params.h's table."""
    tvr = ",\n    ".join(f"t{v.c_name} = {i}" for i, v in enumerate(TRAIN))
    rows = ",\n    ".join(f"{{{v.c_name}, t{v.c_name}, {_C_TYPES[v.type]}, {_c_number(v.name, starts[v.name])}}}"
                          for v in PARAMETERS)
    return ("/* Generated by fmu/train_node.py: the train model's value references (tvr_*) and its parameters "
            "as this node's (net vr, train vr, type, start). */\n#ifndef RG_TRAIN_PARAMS_H\n#define RG_TRAIN_PARAMS_H\n\n"
            "#include <stdint.h>\n\n#include \"net_variables.h\"\n#include \"train_model.h\"\n\n"
            f"enum {{\n    {tvr}\n}};\n\n"
            "typedef struct {\n    uint32_t net;\n    uint32_t train;\n    uint8_t type;\n    double start;\n} rg_train_param;\n\n"
            f"#define N_TRAIN_PARAMS {len(PARAMETERS)}\n\n"
            f"static const rg_train_param TRAIN_PARAMS[N_TRAIN_PARAMS] = {{\n    {rows}\n}};\n\n#endif\n")


def _starts(train_params: dict) -> dict:
    known = {v.name for v in PARAMETERS}
    unknown = sorted(set(train_params) - known)
    if unknown:
        raise BuildError(f"not train parameters: {', '.join(unknown)}")
    return {v.name: train_params.get(v.name, v.start) for v in PARAMETERS}


def train_variables(starts: dict) -> list[NetVar]:
    params = [NetVar(v.name, _TYPES[v.type], "parameter", v.description,
                     bool(starts[v.name]) if v.type == "Boolean" else starts[v.name], "s" if v.unit == "s" else None)
              for v in PARAMETERS]
    return terminal("CAN", "node") + params + [
        NetVar("bit_rate", "Int32", "parameter", "the bit rate this node configures on the bus", BIT_RATE)] + OUTPUTS


def train_spec(train_params: dict, keys: Optional[Path] = None) -> NetworkFmu:
    """The train node with `train_params` (names of fmu.variables.TRAIN, as CosimScenario.train
    has them) as its parameters' start values; `keys` a key folder: secured CAN FD frames."""
    starts = _starts(dict(train_params))
    blob = keys_blob(keys)
    description = ("railguard train dynamics on a CAN bus (FMI-LS-BUS): TrainState and six ObstacleReports every "
                   f"100 ms, BrakeDemand in; {'secured CAN FD' if blob else 'unsecured classical'} frames")
    return NetworkFmu(TRAIN_NODE_ID, "train_node", description, tuple(train_variables(starts)), ("CAN",),
                      extra_sources=FRAME_LAYER + (("core", "rg_core.h"), ("fmi", "rg_math.h"), ("fmi", "rg_reading.h")),
                      extra_files=staged_train_model() + (("train_params.h", params_header(starts)),) + dbc_sources(),
                      resources=((("keys.bin", blob),) if blob else ()), libraries=("-lcrypto",),
                      token_parts=(repr(sorted(starts.items())), "secured" if blob else ""))


def build_train_node(out_dir: Path, train_params: dict, keys: Optional[Path] = None, name: str = "train.fmu") -> Path:
    return build(train_spec(train_params, keys), Path(out_dir) / name)
