"""The scenarios of a campaign: each (draw, sweep value) resolved into a scenario mapping of its own.

:func:`resolve_scenario` builds the scenario of a draw of a :class:`~uh_campaign.spec.CampaignSpec`
(docs/campaigns.md#the-campaign-spec; the module docstring of :mod:`uh_campaign.spec`, *The
resolved scenarios*) from the draw's own random streams (:func:`draw_generators`);
:func:`scenario_yaml` writes it, :func:`scenario_file_name` names its file;
:func:`check_draw_zero` validates the scenarios of draw 0 when a spec is loaded, reporting an
error at the spec key behind it.
"""
from __future__ import annotations

import copy
import re

import numpy as np
import yaml

from uh_controller_node.gains import ControllerGains, GainsError
from uh_core.airframe import load_helicopter_params
from uh_core.layout import CHANNEL_NAMES
from uh_team.separation_metrics import closest_pair_series
from uh_topology import errors as E
from uh_topology.generate import GenerateError, team_mapping
from uh_topology.scenario import scenario_from_mapping
from uh_topology.schema import format_key_path, parse_yaml, read_text_file

from .draws import Draws, FaultDraws, LossDraws, loss_step_range

#: Draws of the initial positions tried for ``draws.min_initial_separation`` before the draw is refused.
POSITION_ATTEMPTS = 1000

__all__ = ['draw_generators', 'scenario_file_name', 'resolve_scenario', 'scenario_yaml', 'check_draw_zero',
           'key_path']

# The independent random streams of a draw, in spawn order (adding a stream at the end keeps the
# others' numbers): each kind of draw has its own, so e.g. a wider position spread leaves the
# drawn faults unchanged.
_STREAMS = ('graph', 'position', 'attitude', 'model_mismatch', 'disturbance', 'faults', 'impairments', 'losses')


_TOKEN = re.compile(r'([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]')


def key_path(text: str) -> tuple:
    """``'a.b[0].c'`` -> ``('a', 'b', 0, 'c')``."""
    return tuple(m.group(1) if m.group(1) is not None else int(m.group(2)) for m in _TOKEN.finditer(text))


# ------------------------------------------------------------------------------------------------
# Resolving a draw


def draw_generators(seed: int, draw: int) -> dict:
    """Give the independent random streams of draw ``draw``, by name.

    They are the children of ``numpy.random.default_rng([seed, draw])``, in a fixed order.
    """
    children = np.random.default_rng([seed, draw]).spawn(len(_STREAMS))
    return dict(zip(_STREAMS, children, strict=True))


def scenario_file_name(spec, draw: int, sweep_index: int) -> str:
    """Name the file of a resolved scenario, relative to the campaign directory.

    ``scenarios/draw_000042.yaml`` (``..._s03.yaml`` with a sweep).
    """
    suffix = f'_s{sweep_index:02d}' if spec.sweep is not None else ''
    return f'scenarios/draw_{draw:06d}{suffix}.yaml'


def resolve_scenario(spec, draw: int, sweep_index: int = 0) -> dict:
    """Give the scenario mapping of (``draw``, ``sweep_index``) of the campaign ``spec``.

    See the module docstring of :mod:`uh_campaign.spec`, *The resolved scenarios*. Plain data, ready
    for :func:`scenario_yaml`. Raises a :class:`~uh_topology.errors.ScenarioError` when a generated
    draw finds no valid graph; the mapping itself is validated when it is loaded.
    """
    rng = draw_generators(spec.seed, draw)
    if spec.generator is not None:
        data = _generated_team(spec, draw, rng['graph'])
    else:
        data = copy.deepcopy(spec.base_mapping)
    sweep = spec.sweep is not None
    data['name'] = f'{spec.name}_draw{draw:06d}' + (f'_s{sweep_index:02d}' if sweep else '')
    what = f'draw {draw} of campaign {spec.name}' + (
        f', {spec.sweep.parameter} = {spec.sweep.values[sweep_index]}' if sweep else '')
    data['description'] = f'{what} (uh-campaign, seed {spec.seed})'
    data['duration'] = spec.duration
    data['settle_time'] = spec.settle_time
    _apply_draws(data, spec.draws, rng)
    if spec.impairments is not None:
        data['impairments'] = copy.deepcopy(spec.impairments)
    if spec.resilience is not None:
        data['resilience'] = copy.deepcopy(spec.resilience)
    if sweep:
        _set_path(data, spec.sweep.path, spec.sweep.values[sweep_index])
    if isinstance(data.get('impairments'), dict):
        data['impairments']['seed'] = int(rng['impairments'].integers(0, 2 ** 31 - 1))
    if spec.safety is not None:
        given = data.get('safety')
        data['safety'] = {**(given if isinstance(given, dict) else {}), **copy.deepcopy(spec.safety)}
    if spec.safety_override is not None:
        given = data.get('safety')
        data['safety'] = {**(given if isinstance(given, dict) else {}), 'enabled': spec.safety_override}
    _apply_remedies(data, spec.remedies or {})
    return data


def _apply_remedies(data: dict, remedies: dict) -> None:
    """Write the spec's ``remedies`` into a resolved scenario: its ``reference_links``, its gains' weight."""
    if 'reference_links' in remedies:
        data['reference_links'] = remedies['reference_links']
    if 'feedforward_weight' in remedies:
        gains = data['gains']
        if isinstance(gains, str):      # a generated team names its gains file: inline it
            gains, _ = parse_yaml(read_text_file(gains), gains)
        gains = copy.deepcopy(gains)
        target = gains['/**']['ros__parameters'] if '/**' in gains else gains
        target['feedforward_weight'] = remedies['feedforward_weight']
        data['gains'] = gains


def _apply_draws(data: dict, draws: Draws, rng: dict) -> None:
    uhs = data['uhs']
    n = len(uhs)
    dp = _position_draw(data, draws, rng['position'])
    tilt = rng['attitude'].uniform(-draws.attitude_spread, draws.attitude_spread, size=(n, 2))
    yaw = rng['attitude'].uniform(-draws.yaw_spread, draws.yaw_spread, size=n)
    for c, uh in enumerate(uhs):
        state = uh['initial_state'] = dict(uh.get('initial_state') or {})
        position = [float(v) for v in state['position']]
        euler = [float(v) for v in state.get('euler', [0.0, 0.0, 0.0])]
        state['position'] = [position[a] + float(dp[c, a]) for a in range(3)]
        state['velocity'] = [float(v) for v in state.get('velocity', [0.0, 0.0, 0.0])]
        state['euler'] = [euler[0] + float(tilt[c, 0]), euler[1] + float(tilt[c, 1]), euler[2] + float(yaw[c])]
        state['omega'] = [float(v) for v in state.get('omega', [0.0, 0.0, 0.0])]
    if draws.model_mismatch is not None:
        data['model_mismatch'] = float(rng['model_mismatch'].uniform(*draws.model_mismatch))
    if draws.disturbance_amplitude is not None:
        dist = data['disturbance'] = dict(data.get('disturbance') or {})
        dist['amplitude'] = [float(v) for v in rng['disturbance'].uniform(*draws.disturbance_amplitude, size=3)]
    if draws.faults is not None:
        data['faults'] = _draw_faults(draws.faults, [int(uh['id']) for uh in uhs], rng['faults'])
    if draws.losses is not None:
        data['events'] = [_draw_loss(draws.losses, [int(uh['id']) for uh in uhs], data, rng['losses'])]


def _position_draw(data: dict, draws: Draws, rng) -> np.ndarray:
    """Draw the initial-position offsets (n, 3), m, until every pair starts ``min_initial_separation`` apart.

    Without that key one draw is taken, as always; with it the draw is repeated from the same stream
    (at most ``POSITION_ATTEMPTS`` times) until the pairs are far enough apart.
    """
    base = np.array([[float(v) for v in uh['initial_state']['position']] for uh in data['uhs']])
    least = draws.min_initial_separation
    for _ in range(POSITION_ATTEMPTS):
        dp = rng.uniform(-draws.position_spread, draws.position_spread, size=base.shape)
        if not least or closest_pair_series((base + dp)[None])[0] >= least:   # one sample: the starts
            return dp
    raise E.InvalidValueError(f'draws.min_initial_separation: no draw of {POSITION_ATTEMPTS} put every pair of '
                              f'initial positions {draws.min_initial_separation:g} m apart; allowed: a smaller '
                              'separation or a larger position_spread')


def _draw_faults(fd: FaultDraws, ids: list, rng) -> list:
    candidates = list(fd.candidates) if fd.candidates is not None else sorted(ids)
    count = int(rng.integers(fd.faulted_uhs[0], fd.faulted_uhs[1] + 1))
    faulted = sorted(int(i) for i in rng.choice(candidates, size=count, replace=False))
    out = []
    for uh in faulted:
        per_uh = int(rng.integers(fd.channels_per_uh[0], fd.channels_per_uh[1] + 1))
        channels = sorted(int(c) for c in rng.choice(fd.channels, size=per_uh, replace=False))
        onset = float(rng.uniform(*fd.onset_time))
        for ch in channels:
            out.append({'uh': uh, 'channel': CHANNEL_NAMES[ch], 'rho': float(rng.uniform(*fd.rho)),
                        'bias_constant': float(rng.uniform(*fd.bias_constant)),
                        'bias_amplitude': float(rng.uniform(*fd.bias_amplitude)),
                        'bias_frequency': float(rng.uniform(*fd.bias_frequency)), 'onset_time': onset})
    return out


def _draw_loss(ld: LossDraws, ids: list, data: dict, rng) -> dict:
    """Draw the lost UH (uniformly among the candidates) and its time, rounded to the scenario's control step.

    A ``stuck`` draw then draws its channel, uniformly among ``ld.channels``.
    """
    candidates = list(ld.uhs) if ld.uhs is not None else sorted(ids)
    uh = int(candidates[int(rng.integers(len(candidates)))])
    dt, duration = float(data['dt']), float(data['duration'])
    first, last = loss_step_range(ld.time, duration, dt)
    step = min(max(int(round(float(rng.uniform(*ld.time)) / dt)), first), last)
    event = {'time': round(step * dt, 9), 'uh': uh, 'kind': ld.kind}
    if ld.kind == 'stuck':
        event['channel'] = CHANNEL_NAMES[int(ld.channels[int(rng.integers(len(ld.channels)))])]
    return event


def _generated_team(spec, draw: int, rng) -> dict:
    """Generate a team with a random graph that passes the topology checks.

    The team is that of :func:`uh_topology.generate.team_mapping`; the graph is redrawn at most
    ``generator.attempts`` times.
    """
    g = spec.generator
    try:
        data = team_mapping(g.leaders, g.followers, duration=spec.duration, faults=False)
    except GenerateError as exc:
        raise E.InvalidValueError(str(exc), path='duration', source=spec.source, line=spec.line('duration')) from None
    data['gains'], _ = parse_yaml(read_text_file(data['gains']), str(data['gains']))
    data['settle_time'] = spec.settle_time
    leaders = list(range(1, g.leaders + 1))
    followers = list(range(g.leaders + 1, g.leaders + g.followers + 1))
    last = None
    for _ in range(g.attempts):
        count = int(rng.integers(g.reference_links[0], g.reference_links[1] + 1))
        linked = sorted(int(i) for i in rng.choice(leaders, size=count, replace=False))
        hears_leader = rng.random((g.leaders, g.leaders)) < g.leader_edge_probability
        hears_any = rng.random((g.followers, g.leaders + g.followers)) < g.follower_edge_probability
        edges = [{'uh': i, 'hears': j, 'weight': 1.0} for i in leaders for j in leaders
                 if i != j and hears_leader[i - 1, j - 1]]
        edges += [{'uh': k, 'hears': j, 'weight': 1.0} for k in followers for j in leaders + followers
                  if j != k and hears_any[k - 1 - g.leaders, j - 1]]
        data['edges'] = edges
        data['reference_links'] = [{'uh': i, 'weight': 1.0} for i in linked]
        if g.weights == 'normalised':
            _normalise_weights(data['edges'], data['reference_links'])
        try:
            scenario_from_mapping(data)
            return data
        except E.TopologyError as exc:
            last = exc
    raise E.InvalidValueError(
        f'draw {draw}: no graph satisfying Assumption 1 in {g.attempts} attempt(s) (last: {last.message}); '
        f'allowed: more attempts or larger edge probabilities', path='generator.attempts', source=spec.source,
        line=spec.line('generator', 'attempts'))


def _normalise_weights(edges: list, links: list) -> None:
    """Divide each UH's incoming weights (``edges`` it hears, its reference ``links``) by their count."""
    heard = {}
    for link in edges + links:
        heard[link['uh']] = heard.get(link['uh'], 0) + 1
    for link in edges + links:
        link['weight'] = 1.0 / heard[link['uh']]


def _set_path(data, tokens: tuple, value) -> None:
    """Write ``value`` at the key path ``tokens`` of ``data``, creating missing mappings."""
    node = data
    for k, token in enumerate(tokens):
        last = k == len(tokens) - 1
        where = format_key_path(tokens[:k + 1])
        if isinstance(token, int):
            if not isinstance(node, list) or token >= len(node):
                raise KeyError(f'{where}: no such list item in the resolved scenario')
        elif not isinstance(node, dict):
            raise KeyError(f'{where}: the scenario has no mapping there')
        elif not last and node.get(token) is None:
            node[token] = {}
        if last:
            node[token] = value
        else:
            node = node[token]


def scenario_yaml(mapping: dict, header: str = '') -> str:
    """Write a resolved scenario as YAML text, after ``header`` (comment lines).

    Floats are written exactly: loading the text gives the same numbers.
    """
    dumper = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)
    body = yaml.dump(mapping, Dumper=dumper, sort_keys=False, default_flow_style=None, width=110)
    return header + body


# ------------------------------------------------------------------------------------------------
# Validation of the resolved scenarios of draw 0


def check_draw_zero(spec) -> None:
    """Build the resolved scenario of draw 0 for every sweep value, the gains of every case and the airframe.

    An error is reported at the spec key it comes from.
    """
    for s in range(len(spec.sweep_values)):
        try:
            data = resolve_scenario(spec, 0, s)
        except KeyError as exc:
            raise E.InvalidValueError(f'{exc.args[0]}; allowed: a key path the scenario has (or mappings to create)',
                                      path='sweep.parameter', source=spec.source,
                                      line=spec.line('sweep', 'parameter')) from None
        try:
            scenario = scenario_from_mapping(data, source=spec.source)
        except E.ScenarioError as exc:
            raise _at_spec_key(spec, exc, s) from None
    try:
        load_helicopter_params(scenario.helicopter)
        for case in spec.cases:
            ControllerGains.from_mapping(scenario.gains, case)
    except (GainsError, ValueError) as exc:
        if isinstance(exc, GainsError) and exc.keys == ('feedforward_weight',) and 'feedforward_weight' in (
                spec.remedies or {}):
            raise E.GainsFileError(str(exc.message), path='remedies.feedforward_weight', source=spec.source,
                                   line=spec.line('remedies', 'feedforward_weight')) from None
        key = 'scenario' if spec.scenario is not None else 'generator'
        raise E.GainsFileError(f'the base scenario\'s gains or airframe cannot be used: {exc}', path=key,
                           source=spec.source, line=spec.line(key)) from None


def _at_spec_key(spec, exc: E.ScenarioError, sweep_index: int) -> E.ScenarioError:
    """``exc`` (raised by the resolved scenario of draw 0) re-raised at the spec key behind it."""
    tokens = key_path(exc.path or '')
    sweep = spec.sweep
    key = None
    if sweep is not None and tokens[:len(sweep.path)] == sweep.path:
        # a key the scenario format does not know is the parameter's fault, not the value's
        key = ('sweep', 'parameter') if isinstance(exc, E.UnknownKeyError) else ('sweep', 'values', sweep_index)
    elif tokens[:1] == ('impairments',) and spec.impairments is not None:
        key = tokens
    elif tokens[:1] == ('reference_links',) and 'reference_links' in (spec.remedies or {}):
        key = ('remedies', 'reference_links')
    elif tokens[:1] in (('duration',), ('settle_time',)) and tokens[:1] in spec.lines:
        key = tokens[:1]
    elif tokens[:1] == ('faults',) and spec.draws.faults is not None:
        key = ('draws', 'faults')
    elif tokens[:1] == ('events',) and spec.draws.losses is not None:
        key = ('draws', 'losses')
    elif tokens[:1] == ('resilience',) and spec.resilience is not None:
        key = tokens
    elif tokens[:1] == ('model_mismatch',) and spec.draws.model_mismatch is not None:
        key = ('draws', 'model_mismatch')
    elif tokens[:1] == ('disturbance',) and spec.draws.disturbance_amplitude is not None:
        key = ('draws', 'disturbance_amplitude')
    elif tokens[:1] == ('uhs',) and (spec.draws.position_spread or spec.draws.attitude_spread
                                     or spec.draws.yaw_spread):
        key = ('draws',)
    if key is None:
        key = ('scenario',) if spec.scenario is not None else ('generator',)
    what = 'draw 0' + (f' with {sweep.parameter} = {sweep.values[sweep_index]!r}' if sweep is not None else '')
    message = f'{exc.message} (the resolved scenario of {what}, at its key {exc.path or "(top)"})'
    kwargs = {'ids': exc.ids} if hasattr(exc, 'ids') else {}
    return type(exc)(message, path=format_key_path(key), source=spec.source, line=spec.line(*key), **kwargs)
