"""The papers' risk figures from the live signal (issue 31 item 6): seed 000's Fig. 7c and
seed 001's risk accuracy read off what the monitor sent on the bus in recorded runs.

`bus_log` reads a candump log with the users' tools (python-can, cantools and the DBC),
`players` plays the seed worlds on the in-process bus, `part` is the verification part.
"""
from .part import TITLE, section

__all__ = ["TITLE", "section"]
