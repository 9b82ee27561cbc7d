"""`python -m railguard ...` is the same as the `railguard` command."""
from .main import entry

entry()
