"""Parameters of the controller node besides the run parameters: the variant, the synchroniser's timing, the gains.

``case`` (``proposed``, ``case1``, ``case2``), the realtime timing of
:class:`~uh_controller_node.input_sync.InputSynchroniser` (``sync_wait``, ``stale_timeout``,
``startup_grace``) and every gain of the scenario's gains file as a parameter of its own
(``beta``, ``outer.k`` ...; docs/control_law.md#gains-as-parameters): the file's value is the
default, ``--params-file`` (``/**:``) or ``-p`` override it, and a change at run time is accepted
only if the gains it makes pass the gains file's checks.
"""
from __future__ import annotations

import uh_runtime as rt
from uh_controller_node.gains import (
    CASES,
    ControllerGains,
    GainsError,
    gain_parameters,
    gains_source,
    located,
    nest_gains,
)
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT, RunConfigError, declare_float_parameter

__all__ = ['SYNC_PARAMETERS', 'declare_controller_parameters', 'GainParameters']

#: Floating-point parameters of the synchroniser: (name, default, upper bound, description).
SYNC_PARAMETERS = (
    ('sync_wait', 0.004, 1.0,
     'realtime: wall seconds to wait for same-step neighbour data before using the latest'),
    ('stale_timeout', DEFAULT_STALE_TIMEOUT, 60.0,
     'realtime: simulated seconds a neighbour\'s state (or the reference) may lag the own '
     'state before it is reported stale and left out of the control law'),
    ('startup_grace', 1.0, 600.0,
     'realtime: wall seconds after the first own state before an input never heard is stale'),
)


def declare_controller_parameters(node) -> tuple[str, dict]:
    """Declare ``case`` and the synchroniser's parameters on ``node``.

    Returns the case (checked against :data:`~uh_controller_node.gains.CASES`; else
    :class:`~uh_wire.run_config.RunConfigError`) and ``{name: value}`` of :data:`SYNC_PARAMETERS`.
    """
    node.declare_parameter('case', 'proposed', rt.ParameterDescriptor(
        description='controller variant: proposed, case1 (beta = 1), case2 (no serial-parallel '
                    'estimation model)', read_only=True))
    sync = {name: declare_float_parameter(node, name, default, upper, text)
            for name, default, upper, text in SYNC_PARAMETERS}
    case = str(node.get_parameter('case').value)
    if case not in CASES:
        raise RunConfigError(f"parameter 'case' is {case!r}; allowed: {', '.join(CASES)}")
    return case, sync


class GainParameters:
    """The gains of a controller node as parameters, declared from the scenario's gains file.

    Parameters
    ----------
    node
        The controller node (declares the parameters, logs rejected changes).
    scenario
        The scenario (:class:`uh_topology.scenario.Scenario`) whose gains are declared.
    case : str
        The controller variant the gains are for.
    uh_id : int
        The node's UH (named in errors).
    """

    def __init__(self, node, scenario, case: str, uh_id: int):
        self.node, self.case, self.uh_id = node, case, uh_id
        names = []
        try:
            parameters = gain_parameters(scenario.gains, source=gains_source(scenario))
        except GainsError as exc:
            raise located(exc, scenario) from None
        for g in parameters:
            ranges = {}
            if isinstance(g.value, int):
                ranges['integer_range'] = [rt.IntegerRange(from_value=1, to_value=100000, step=1)]
            elif g.minimum is not None:
                ranges['floating_point_range'] = [rt.FloatingPointRange(from_value=g.minimum, to_value=1e12, step=0.0)]
            node.declare_parameter(g.name, g.value, rt.ParameterDescriptor(
                description=g.description, read_only=g.read_only, **ranges))
            names.append(g.name)
        self.names = tuple(names)

    def gains(self, changes: dict | None = None) -> ControllerGains:
        """Return the gains of the current parameter values with ``changes`` applied.

        Validated like the gains file: :class:`~uh_controller_node.gains.GainsError` says what is wrong.
        """
        flat = {name: self.node.get_parameter(name).value for name in self.names}
        flat.update(changes or {})
        return ControllerGains.from_mapping(nest_gains(flat), self.case, source=f'uh{self.uh_id} controller gains')

    def changed(self, params) -> list:
        """Return the parameters of ``params`` that are gains."""
        return [p for p in params if p.name in self.names]

    def check(self, params):
        """Accept a change of gains only if the gains it makes pass the gains file's checks."""
        changes = {p.name: p.value for p in self.changed(params)}
        if changes:
            try:
                self.gains(changes)
            except GainsError as exc:
                self.node.get_logger().warning(f'gain change {changes} rejected: {exc}')
                return rt.SetParametersResult(successful=False, reason=str(exc))
        return rt.SetParametersResult(successful=True)
