"""One module per subcommand; each has `register(sub)` that adds its parser and sets
`func` to the function that runs it (returning the exit status)."""
from . import (build_fmu, campaign, cosim, evaluate, keys, play, replay, run, scenarios, solve, stress, table,
               verify)

ALL = (run, play, replay, cosim, build_fmu, solve, evaluate, table, scenarios, verify, campaign, stress, keys)
