"""The ``hoibench`` subcommands, one module per group; :mod:`hoibench.cli` dispatches to them.

Each module's ``register(subparsers)`` adds its parsers and sets each one's handler
(``set_defaults(func=...)``, a function of the parsed arguments returning the exit status).
:data:`MODULES` lists the groups in the order ``hoibench --help`` shows their commands.
Handlers are CLI glue (checks of options, printing, exit codes); the work is done by the
library functions of the pipeline stages they call."""
from __future__ import annotations

from . import audit, baselines, challenge, data, demo, evaluators, leaderboard, publish, scoring

#: the command modules, in ``hoibench --help`` order
MODULES = (data, scoring, evaluators, audit, baselines, publish, leaderboard, challenge, demo)
