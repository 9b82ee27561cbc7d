"""Shipped braking declarations (TOML, SI units; docs/supervision.md)."""
