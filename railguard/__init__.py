"""The `railguard` command line: the shell above the others.

One small module per subcommand in `railguard.commands`; what they share (options, errors,
output conventions) in `railguard.options`, `railguard.errors` and `railguard.output`.
Nothing in monitor, can_bus, fmu or verification imports this package.
"""
from monitor import __version__

__all__ = ["__version__"]
