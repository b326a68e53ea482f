"""The defaults of a team run and the choices of its options: the one module the run's entry points import them from.

``scripts/run_formation.sh`` (:mod:`uh_bringup.run_formation`), ``formation.launch.py``
(:mod:`uh_bringup.launch_run`) and the nodes take from here the clock modes, the node backends,
how long the clock waits for the team's nodes to come up and when a neighbour's data is stale.
The lists are defined where they are checked: :data:`BACKENDS` by the runtime that selects a
backend (:mod:`uh_runtime.backend`), :data:`CLOCK_MODES` and :data:`DEFAULT_STALE_TIMEOUT` with
the run parameters every node declares (:mod:`uh_wire.run_config`).
"""
from __future__ import annotations

from uh_runtime.backend import BACKENDS
from uh_wire.run_config import CLOCK_MODES, DEFAULT_STALE_TIMEOUT

__all__ = ['BACKENDS', 'CLOCK_MODES', 'DEFAULT_STALE_TIMEOUT', 'DEFAULT_STARTUP_TIMEOUT']

#: s the clock waits for every node of the team to come up before it gives up on the run
#: (``--startup-timeout`` of the run, launch argument and clock parameter ``startup_timeout``; a
#: launch counts it once the kernels are compiled).
DEFAULT_STARTUP_TIMEOUT = 60.0
