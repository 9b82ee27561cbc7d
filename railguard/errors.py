"""What a user can get wrong, and how it is shown: one line on stderr, exit code 2.

Every shell has its own exception for bad input; they are collected here so that `main`
turns each into one line and nothing else escapes as a traceback.
"""
from __future__ import annotations

from contextlib import contextmanager

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


class UserError(Exception):
    """A problem with the user's input, shown as one line."""


def user_errors() -> tuple[type[BaseException], ...]:
    """The exception types that mean "bad input", from every layer that is installed."""
    import zipfile

    from monitor.core.config import ConfigurationError
    from monitor.core.table import TableError
    from monitor.declaration import DeclarationError
    from monitor.offline.params import ConfigError
    from monitor.offline.pomdp import ModelError
    from monitor.offline.pomdp_file import PomdpFormatError
    from monitor.scenario import ScenarioError as GroundScenarioError
    from verification.scale import ClusterError
    from verification.world_train import WorldTrainError

    errors = [UserError, TableError, ConfigError, ModelError, PomdpFormatError, ConfigurationError, DeclarationError,
              WorldTrainError, ClusterError, GroundScenarioError, OSError, zipfile.BadZipFile]
    try:
        import can

        from can_bus.keys import KeyFileError
        from can_bus.replay import ReplayError
        from can_bus.scenario import ScenarioError
        from can_bus.session import BusOpenError, MonitorNotReady

        errors += [ScenarioError, ReplayError, BusOpenError, MonitorNotReady, can.CanError, KeyFileError]
    except ImportError:  # the CAN shell is optional for the offline commands
        pass
    try:
        from fmu.build import BuildError
        from fmu.cosim import CosimError
        from fmu.driver import FmuFileError
        from fmu.scenario import CosimScenarioError

        errors += [BuildError, CosimError, CosimScenarioError, FmuFileError]
    except ImportError:  # the FMU shell is optional too
        pass
    return tuple(errors)


def one_line(exc: BaseException) -> str:
    """The first line of an error, with the file name for OS errors."""
    if isinstance(exc, OSError) and getattr(exc, "filename", None) and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


@contextmanager
def naming(path, *types: type[BaseException]):
    """Errors of `types` raised while reading the user's file `path` name that file."""
    try:
        yield
    except types as exc:
        if path and not one_line(exc).startswith(str(path)):
            raise UserError(f"{path}: {one_line(exc)}") from None
        raise
