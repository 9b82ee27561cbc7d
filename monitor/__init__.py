"""railguard: a railway anti-collision safety monitor (offline POMDP tables, online cyclic core)."""

__version__ = "0.1.0"
