"""Build the FMUs: generate the sources, compile the linux64 binary with gcc, zip.

    build_monitor(table_bytes, fmi=2|3, out_dir, config=None) -> path of railguard-monitor-<model>-fmi<n>.fmu
    build_train(out_dir)                                        -> path of railguard-train-fmi2.fmu

`config` (a monitor.core.config.Config, e.g. a braking declaration applied to the
defaults) gives the monitor's parameter start values, in the model description and in
the C start values alike, so an importer that sets no parameter runs that configuration.

Each FMU carries its C sources (with the FMI 3.0 buildDescription.xml) so that others can
compile it for their platform; the binary is built with -std=c99 -Wall -Wextra -Werror
-pedantic, so a warning is a build failure. Builds are deterministic: the same table and
sources give the same modelDescription and the same sources in the archive.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

from monitor.core.config import Config, ConfigurationError, check
from monitor.core.table import TableError, decode

from . import generate
from .variables import MONITOR, TRAIN, parameter_starts

C_DIR = Path(__file__).resolve().parent / "c"
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-fPIC"]
PLATFORM = {2: "linux64", 3: "x86_64-linux"}
TRAIN_TOKEN = "{4b9cae65-a4cc-4688-ac28-c403b5610c64}"
MONITOR_ID = "railguard_monitor"
TRAIN_ID = "railguard_train"
CORE_SOURCES = ["rg_core.c", "rg_sha256.c"]
CORE_HEADERS = ["rg_core.h", "rg_sha256.h"]


class BuildError(RuntimeError):
    """The FMU could not be built; the message says why (compiler output included)."""


def fmi_include_dir() -> Path:
    import fmpy

    return Path(fmpy.__file__).resolve().parent / "c-code"


def compiler() -> str:
    cc = os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        raise BuildError(f"no C compiler: {cc!r} not found (install gcc, or set CC)")
    return cc


def compile_binary(sources_dir: Path, files: list[str], output: Path, defines: list[str] = (),
                   libraries: list[str] = ()) -> None:
    """gcc the flat source folder into a shared library; warnings are errors."""
    output.parent.mkdir(parents=True, exist_ok=True)
    cmd = [compiler(), *CFLAGS, "-shared", *(f"-D{d}" for d in defines), f"-I{fmi_include_dir()}",
           f"-I{sources_dir}", *(str(sources_dir / f) for f in files), "-o", str(output), "-lm",
           *libraries]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BuildError(f"compiling {output.name} failed:\n{res.stderr.strip()}")


def _zip(folder: Path, target: Path) -> Path:
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_suffix(".fmu.part")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                info = zipfile.ZipInfo(path.relative_to(folder).as_posix(), date_time=(2026, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                zf.writestr(info, path.read_bytes())
    tmp.replace(target)
    return target


def _stage(folder: Path, model: str, variables, extra: dict[str, str], core: bool,
           core_dir: Path | None = None) -> list[str]:
    """Copy the core (from `core_dir`, default fmu/c/core), the FMI wrapper contract and the
    model into folder/sources; write the generated files. Returns the list of .c files."""
    src = folder / "sources"
    src.mkdir(parents=True)
    for name in (CORE_SOURCES + CORE_HEADERS) if core else ():
        shutil.copy(Path(core_dir or C_DIR / "core") / name, src / name)
    for name in ("model.h", "rg_math.h", "rg_reading.h", "rg_fmi_shared.h"):
        shutil.copy(C_DIR / "fmi" / name, src / name)
    for path in sorted((C_DIR / model).glob("*.[ch]")):
        shutil.copy(path, src / path.name)
    (src / "variables.h").write_text(generate.variables_header(variables))
    (src / "variables.c").write_text(generate.variables_source(variables))
    for name, text in extra.items():
        (src / name).write_text(text)
    return sorted(p.name for p in src.glob("*.c"))


def _finish(folder: Path, identifier: str, fmi: int, c_files: list[str], description: str, out: Path) -> Path:
    src = folder / "sources"
    wrapper = f"fmi{fmi}.c"
    shutil.copy(C_DIR / "fmi" / wrapper, src / wrapper)
    files = sorted(c_files + [wrapper])
    if fmi == 3:
        (src / "buildDescription.xml").write_text(generate.build_description_fmi3(identifier, files))
    (folder / "modelDescription.xml").write_text(description)
    compile_binary(src, files, folder / "binaries" / PLATFORM[fmi] / f"{identifier}.so",
                   defines=["DISABLE_PREFIX"] if fmi == 3 else [])
    return _zip(folder, out)


def monitor_starts(config: Config, period_ms: int) -> dict:
    """The parameter start values for `config`, checked as the core checks them; its period
    must be the table's (the FMU's fixed step)."""
    try:
        check(config)
    except ConfigurationError as exc:
        raise BuildError(f"configuration refused: {exc}") from None
    if config.period_ms != period_ms:
        raise BuildError(f"period_ms = {config.period_ms}: the table was solved for {period_ms} ms, the FMU's fixed step")
    return parameter_starts(config)


def build_monitor(data: bytes, fmi: int = 2, out_dir: str | Path = ".", name: str | None = None,
                  config: Config | None = None, core_dir: str | Path | None = None) -> Path:
    """The monitor FMU for the table `data` (the bytes of a .rgt file); its parameters start
    at `config`'s values (default: Config(), the shipped declaration). `core_dir`: the core's
    C sources from there instead of fmu/c/core (a planted weakening's replay)."""
    if fmi not in (2, 3):
        raise BuildError(f"FMI version {fmi} is not supported (2 or 3)")
    try:
        table = decode(data)
    except TableError as exc:
        raise BuildError(f"table refused: {exc}") from None
    if table.model not in ("m1", "m2"):
        raise BuildError(f"table is for model {table.model!r}; the monitor FMU runs m1 or m2 tables")
    params = monitor_starts(config or Config(), round(float(table.header["params"]["time_step_s"]) * 1000))
    tok = generate.token(MONITOR_ID, str(fmi), table.sha256, generate.variables_signature(MONITOR),
                         repr(sorted(params.items())))
    starts = {"table.model": table.model, "table.sha256": table.sha256, "table.nodes": table.nodes, **params}
    description = (f"railguard anti-collision monitor, policy table {table.model} ({table.nodes} nodes, "
                   f"sha256 {table.sha256[:12]}), 2oo2/3oo3 voting, braking curves, 100 ms cycle")
    out = Path(out_dir) / (name or f"railguard-monitor-{table.model}-fmi{fmi}.fmu")
    with tempfile.TemporaryDirectory(prefix="railguard-fmu-") as tmp:
        folder = Path(tmp)
        c_files = _stage(folder, "monitor", MONITOR, {"rg_table.h": generate.table_header(table, data),
                                                      "rg_parameters.h": generate.parameters_header(params),
                                                      "build_info.h": generate.build_info_header(tok)}, core=True,
                         core_dir=Path(core_dir) if core_dir else None)
        if fmi == 2:
            xml = generate.model_description_fmi2(MONITOR_ID, tok, description, MONITOR, c_files + ["fmi2.c"],
                                                  0.1, 60.0, starts)
        else:
            xml = generate.model_description_fmi3(MONITOR_ID, tok, description, MONITOR, 0.1, 60.0, starts)
        return _finish(folder, MONITOR_ID, fmi, c_files, xml, out)


def build_train(out_dir: str | Path = ".", name: str | None = None) -> Path:
    """The train-dynamics FMU (FMI 2.0 Co-Simulation)."""
    out = Path(out_dir) / (name or "railguard-train-fmi2.fmu")
    description = ("railguard train dynamics: Davis resistance, gradient, brake delay and build-up, "
                   "obstacle scenario, six sensor channels with seeded noise and fault injection")
    with tempfile.TemporaryDirectory(prefix="railguard-fmu-") as tmp:
        folder = Path(tmp)
        c_files = _stage(folder, "train", TRAIN, {}, core=False)
        xml = generate.model_description_fmi2(TRAIN_ID, TRAIN_TOKEN, description, TRAIN, c_files + ["fmi2.c"],
                                              0.01, 60.0)
        return _finish(folder, TRAIN_ID, 2, c_files, xml, out)
