"""The campaign spec: one YAML file describing a Monte Carlo campaign of in-process team runs.

A campaign runs ``runs`` random *draws* of a team scenario, each for every controller case of
``cases`` and, with a ``sweep``, for every swept value: ``runs x len(sweep.values) x len(cases)``
runs in all. A draw is a scenario: the base scenario (or a randomly generated team) with random
initial states, actuator faults, model mismatch and disturbance drawn from the ranges below.

Example (``uh_topology/uh_topology/config/campaign_paper_faults.yaml`` is a commented one)::

    name: paper_faults            # str, required: names the campaign and its resolved scenarios
    description: ...              # str, optional
    scenario: paper               # the base scenario: bundled name or path relative to this file
    runs: 200                     # int >= 1, required: number of draws
    seed: 2025                    # int >= 0, default 0
    duration: 60.0                # s, optional: replaces the scenario's duration
    cases: [proposed, case1, case2]
    success: {formation_rms_m: 0.05, containment_rms_m: 0.02}
    draws:
      position_spread: 2.0        # m
      attitude_spread: 0.1        # rad
      faults: {faulted_uhs: [1, 3], rho: [0.7, 0.95], onset_time: [10, 30]}
    impairments: {loss: 0.05}     # optional, copied into every resolved scenario
    sweep: {parameter: impairments.delay_steps, values: [0, 2, 5, 10, 20]}

Top-level keys
--------------
``name`` (required)
    String; the campaign's name (stored in the results, prefix of the resolved scenarios' names).
``description``
    String, default ``''``.
``scenario``
    The base scenario (docs/scenario.md): a file name relative to the spec's directory (or
    absolute), or the name of a bundled scenario (``paper``, ``square``, ``wide``). Exactly one of
    ``scenario`` and ``generator`` is required.
``generator``
    Instead of a base scenario, a random communication graph per draw (see *Generator* below).
``runs`` (required)
    Number of draws, integer >= 1 (``uh-campaign --runs N`` replaces it).
``seed``
    Integer >= 0, default 0. Draw ``i`` uses its own generator
    ``numpy.random.default_rng([seed, i])`` and nothing else, so a draw does not depend on the
    order in which draws run, on the number of workers, nor on ``runs``.
``duration``
    Simulated seconds of every run, > 0 and a whole number of the scenario's ``dt``; default: the
    base scenario's duration (60 s for a generated team).
``settle_time``
    Start of the after-settle metrics, s, in [0, duration). Default: the base scenario's
    ``settle_time`` (20 s for a generated team) when it is shorter than the duration, otherwise
    half the duration (so short test campaigns need not set it).
``cases``
    Non-empty list of controller cases without repeats, from ``proposed``, ``case1``, ``case2``
    (docs/control_law.md#comparison-cases); default all three. Every case runs the same draws.
``success``
    Mapping ``metric: threshold``: a run succeeds when it ended ``ok`` and every named metric is
    ``<=`` its threshold (a metric without a value counts as not met). Metrics: the columns of
    :data:`uh_team.campaign_store.METRIC_COLUMNS`. Default ``{formation_rms_m: 0.05,
    containment_rms_m: 0.02}`` (m); a given mapping replaces the default (``{}``: every ``ok``
    run succeeds).
``impairments``
    Optional mapping, the scenario key ``impairments`` (docs/scenario.md): delays, jitter, losses,
    noise, dropouts of the communication and the controllers' ``delay_compensation``. Copied into
    every resolved scenario (replacing any of the base scenario). Its ``seed`` is not given here:
    each draw gets its own, drawn from the draw's generator, so loss and noise patterns differ
    between draws and repeat for the same draw (the seed of impairments that come from the base
    scenario or a sweep is replaced the same way).
``sweep``
    Optional mapping ``{parameter, values}``: every draw is run once per value, with the value
    written at ``parameter`` of the resolved scenario. ``parameter`` is a key path into the
    scenario mapping, dotted, with ``[i]`` for list items: ``impairments.delay_steps``,
    ``impairments.loss``, ``model_mismatch``, ``disturbance.amplitude[2]``,
    ``uhs[0].initial_state.omega[0]``. Missing mappings on the way are created (a sweep of
    ``impairments.loss`` needs no ``impairments`` key). ``values``: a non-empty list of numbers
    without repeats. A parameter the draws set (``model_mismatch`` with ``draws.model_mismatch``,
    ``faults...`` with ``draws.faults``, ``disturbance.amplitude`` with
    ``draws.disturbance_amplitude``, initial positions or attitudes with a spread) or
    ``impairments.seed`` cannot be swept.
``draws``
    Optional mapping of the random draws (below); without it every draw is the base scenario
    (only the impairments seed and a generated graph differ between draws).

``draws``
---------
Ranges are lists ``[low, high]`` with ``low <= high`` (``low == high``: a fixed value); numbers
are drawn uniformly in ``[low, high]``, integer ranges uniformly among ``low..high``.

``position_spread``
    m, >= 0, default 0: every UH's initial position moves by a uniform draw in
    ``[-spread, spread]`` per axis.
``attitude_spread``
    rad, in [0, pi/2), default 0: roll and pitch move by a uniform draw in ``[-spread, spread]``
    (the base scenario's largest roll or pitch plus the spread must stay below pi/2).
``yaw_spread``
    rad, >= 0, default 0: the initial yaw moves by a uniform draw in ``[-spread, spread]``.
``model_mismatch``
    Range, low > 0: replaces the scenario's ``model_mismatch`` (factor on the controller's nominal
    ``D_v`` and ``c_Q``; 1 = exact).
``disturbance_amplitude``
    Range in N, low >= 0: each axis of the disturbance amplitude is drawn from it (frequencies and
    phases stay the scenario's).
``faults``
    Mapping; when given, the drawn faults replace the scenario's. Keys (all optional):

    ``faulted_uhs``
        Integer range, default ``[1, 1]``: how many UHs get faults (0 allowed), at most the
        number of ``candidates``.
    ``candidates``
        List of UH ids that may be faulted, default every UH.
    ``channels``
        List of channels that may fault (names ``collective``, ``tail_rotor``, ``lateral``,
        ``longitudinal``, their symbols ``theta_col``, ... or indices 0..3), default all four.
    ``channels_per_uh``
        Integer range, default ``[1, 1]``: faulted channels per faulted UH, 1..len(channels).
    ``rho``
        Range within (0, 1], default ``[0.7, 0.95]``: remaining effectiveness (rho = 0, a stuck
        actuator, is outside what the controller compensates).
    ``bias_constant``
        Range, rad, default ``[0, 0]``.
    ``bias_amplitude``
        Range, rad, low >= 0, default ``[0, 0]``.
    ``bias_frequency``
        Range, rad/s, low >= 0, default ``[0, 0]``.
    ``onset_time``
        Range, s, low >= 0, default ``[10, 10]``: one onset per faulted UH, shared by its channels.
        Keep it after the controllers' learning phase (8 s with the paper's gains).

Faulted UHs are chosen without repeats among the candidates, channels without repeats among
``channels``.

``generator``
-------------
A random team per draw, satisfying Assumption 1 of the paper (docs/graph.md): offsets, initial
positions, reference, disturbance and gains are those of :func:`uh_topology.generate.team_mapping`
(leaders on a circle, the paper's trajectory and gains); the graph is drawn:

``leaders`` (required)
    N, integer >= 1.
``followers`` (required)
    M, integer >= 1.
``reference_links``
    Integer range within 1..N, default ``[1, 1]``: how many leaders (chosen at random) hear the
    virtual leader (weight 1).
``leader_edge_probability``
    In [0, 1], default 0.5: each leader hears each other leader with this probability (weight 1).
``follower_edge_probability``
    In (0, 1], default 0.5: each follower hears each leader and each other follower with this
    probability (weight 1). Leaders never hear followers.
``weights``
    ``unit`` (default: every link weight 1, as the paper's graph) or ``normalised``: each UH's
    incoming weights (its edges and its reference link) are ``1 / d_i``, ``d_i`` the number of
    UHs (and virtual leader) it hears, so they sum to 1 and a UH's consensus error, and with it its
    command, does not grow with how many it hears (docs/campaigns.md#second-study-random-graphs).
    The same graphs are drawn either way.
``attempts``
    Integer >= 1, default 100: a drawn graph that fails the topology checks of
    :func:`uh_topology.scenario.scenario_from_mapping` (the source of truth) is redrawn, from the
    same draw's generator, at most this many times; a draw without a valid graph after that is
    recorded as ``failed``.

A spec whose generator cannot satisfy Assumption 1 (no follower edges, or leaders that can never
all be reached: ``leader_edge_probability: 0`` with fewer reference links than leaders) is
refused, as is one whose draw 0 finds no valid graph.

The resolved scenarios
----------------------
:func:`resolve_scenario` builds the scenario mapping of a (draw, sweep index): base (or generated)
scenario, then duration and settle time, the draws, the impairments (with the draw's seed), then
the sweep value. It names the scenario ``<name>_draw<i>[_s<j>]``, holds the gains inline and the
helicopter as a bundled name or an absolute path, so the YAML written by :func:`scenario_yaml`
loads on its own with :func:`uh_topology.scenario.load_scenario`.

Errors
------
Loading a spec raises the :mod:`uh_topology.errors` types of scenario loading, with the spec's
file, line and key path (``spec.yaml:12: draws.faults.rho: ...``): syntax errors, unknown or
missing keys, wrong types, values out of range, inverted ranges. The resolved scenario of draw 0
for every sweep value is validated too (and the gains for every case), and an error in it is
reported at the spec key that caused it (the sweep value, the impairments entry, ...).
"""
from __future__ import annotations

import copy
import hashlib
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from uh_controller_node.gains import CASES, ControllerGains, GainsError
from uh_core.airframe import load_helicopter_params
from uh_core.layout import CHANNEL_NAMES
from uh_topology import errors as E
from uh_topology.generate import GenerateError, team_mapping
from uh_topology.scenario import DEFAULT_SETTLE_TIME, bundled_scenarios, parse_scenario, scenario_from_mapping
from uh_topology.schema import (CONFIG_DIR, ConfigContext, format_key_path, parse_yaml, read_config_file,
                                type_name, unit_suffix)

from uh_team.campaign_store import METRIC_COLUMNS

__all__ = ['CampaignSpec', 'Draws', 'FaultDraws', 'GeneratorSpec', 'Sweep', 'load_spec', 'parse_spec',
           'bundled_specs', 'resolve_scenario', 'scenario_yaml', 'scenario_file_name', 'draw_generators',
           'DEFAULT_SUCCESS', 'BUNDLED_PREFIX']

#: Bundled specs are ``uh_topology/config/campaign_*.yaml``.
BUNDLED_PREFIX = 'campaign_'

#: Default success thresholds: metric -> largest value that still succeeds (m).
DEFAULT_SUCCESS = {'formation_rms_m': 0.05, 'containment_rms_m': 0.02}

_TOP_REQUIRED = ('name', 'runs')
_TOP_OPTIONAL = ('description', 'scenario', 'generator', 'seed', 'duration', 'settle_time', 'cases',
                 'success', 'impairments', 'sweep', 'draws')
_DRAW_KEYS = ('position_spread', 'attitude_spread', 'yaw_spread', 'model_mismatch', 'disturbance_amplitude',
              'faults')
_FAULT_KEYS = ('faulted_uhs', 'candidates', 'channels', 'channels_per_uh', 'rho', 'bias_constant',
               'bias_amplitude', 'bias_frequency', 'onset_time')
_GENERATOR_REQUIRED = ('leaders', 'followers')
_GENERATOR_OPTIONAL = ('reference_links', 'leader_edge_probability', 'follower_edge_probability', 'weights',
                       'attempts')
#: The link weights a generator can give (``generator.weights``).
GENERATOR_WEIGHTS = ('unit', 'normalised')

# The independent random streams of a draw, in spawn order (adding a stream at the end keeps the
# others' numbers): each kind of draw has its own, so e.g. a wider position spread leaves the
# drawn faults unchanged.
_STREAMS = ('graph', 'position', 'attitude', 'model_mismatch', 'disturbance', 'faults', 'impairments')

_KEY_PATH = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*|\[\d+\])*\Z')
_TOKEN = re.compile(r'([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]')


# ------------------------------------------------------------------------------------------------
# Plain validated data


@dataclass(frozen=True)
class FaultDraws:
    """The fault draws of ``draws.faults`` (module docstring).

    Ranges are ``(low, high)``; ``channels`` are channel indices, ``candidates`` UH ids (None:
    every UH).
    """

    faulted_uhs: tuple = (1, 1)
    candidates: tuple | None = None
    channels: tuple = (0, 1, 2, 3)
    channels_per_uh: tuple = (1, 1)
    rho: tuple = (0.7, 0.95)
    bias_constant: tuple = (0.0, 0.0)       # rad
    bias_amplitude: tuple = (0.0, 0.0)      # rad
    bias_frequency: tuple = (0.0, 0.0)      # rad/s
    onset_time: tuple = (10.0, 10.0)        # s


@dataclass(frozen=True)
class Draws:
    """The random draws of a campaign (module docstring).

    Spreads in m and rad, ranges ``(low, high)`` or None (not drawn).
    """

    position_spread: float = 0.0        # m
    attitude_spread: float = 0.0        # rad, roll and pitch
    yaw_spread: float = 0.0             # rad
    model_mismatch: tuple | None = None
    disturbance_amplitude: tuple | None = None   # N
    faults: FaultDraws | None = None


@dataclass(frozen=True)
class GeneratorSpec:
    """Random graphs with N leaders and M followers (module docstring)."""

    leaders: int
    followers: int
    reference_links: tuple = (1, 1)
    leader_edge_probability: float = 0.5
    follower_edge_probability: float = 0.5
    attempts: int = 100
    weights: str = 'unit'


@dataclass(frozen=True)
class Sweep:
    """The swept parameter of a campaign.

    ``parameter`` (the key path as written), ``path`` (its tokens: str keys, int list indices)
    and ``values`` (numbers, as written).
    """

    parameter: str
    path: tuple
    values: tuple


@dataclass(frozen=True, eq=False)
class CampaignSpec:
    """A validated campaign spec (module docstring). Build it with :func:`load_spec`.

    Attributes
    ----------
    name, description : str
    source : str or None
        The spec file (or None for text without a file).
    text : str
        The spec's text, as read.
    base_dir : Path
        Directory of the spec (relative file names are resolved against it).
    scenario : str or None
        The base scenario file (absolute path), None with a generator.
    generator : GeneratorSpec or None
    runs, seed : int
    duration, settle_time : float
        s (the effective values; settle_time may have been lowered to half the duration).
    cases : tuple of str
    success : dict
        metric -> threshold.
    impairments : dict or None
        The fixed impairments mapping (without seed).
    sweep : Sweep or None
    draws : Draws
    """

    name: str
    description: str
    source: str | None
    text: str
    base_dir: Path
    scenario: str | None
    generator: GeneratorSpec | None
    runs: int
    seed: int
    duration: float
    settle_time: float
    cases: tuple
    success: dict
    impairments: dict | None
    sweep: Sweep | None
    draws: Draws
    runs_override: int | None = None
    lines: dict = field(default_factory=dict, repr=False)
    base_mapping: dict | None = field(default=None, repr=False)   # the self-contained base scenario

    @property
    def sweep_values(self) -> tuple:
        """The swept values, ``(None,)`` without a sweep (one sweep point)."""
        return self.sweep.values if self.sweep is not None else (None,)

    @property
    def total_runs(self) -> int:
        """Runs of the whole campaign: draws x sweep points x cases."""
        return self.runs * len(self.sweep_values) * len(self.cases)

    @property
    def digest(self) -> str:
        """Identify the campaign a results file belongs to.

        The sha256 of the spec text, of the base scenario it resolves to (with its gains, so
        editing the scenario or gains file is a new campaign) and of the ``--runs`` override, if any.
        """
        h = hashlib.sha256(self.text.encode())
        if self.base_mapping is not None:
            h.update(b'\n' + yaml.safe_dump(self.base_mapping, sort_keys=True).encode())
        if self.runs_override is not None:
            h.update(f'\n--runs {self.runs_override}'.encode())
        return h.hexdigest()

    def with_runs(self, runs: int) -> 'CampaignSpec':
        """Give the spec with ``runs`` draws.

        The ``--runs`` override; the spec's own number changes nothing, not even the digest.
        """
        if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
            raise E.InvalidValueError(f'--runs must be an integer >= 1, got {runs!r}')
        if runs == self.runs and self.runs_override is None:
            return self
        return replace(self, runs=runs, runs_override=runs)

    def units(self):
        """Every run key ``(draw, sweep_index, case)``, draw-major."""
        for draw in range(self.runs):
            for s in range(len(self.sweep_values)):
                for case in self.cases:
                    yield draw, s, case

    def line(self, *path) -> int | None:
        """Line of a key path of the spec."""
        return ConfigContext(self.source, self.lines).line(path)


# ------------------------------------------------------------------------------------------------
# Loading


def bundled_specs() -> tuple:
    """Names of the bundled campaign specs (``uh_topology/config/campaign_*.yaml``)."""
    return tuple(sorted(p.stem for p in CONFIG_DIR.glob(f'{BUNDLED_PREFIX}*.yaml')))


def load_spec(path_or_name) -> CampaignSpec:
    """Load and validate a campaign spec.

    A YAML file, or the name of a bundled spec (``campaign_paper_faults``). Raises the
    :mod:`uh_topology.errors` types (module docstring).
    """
    path, content = read_config_file(path_or_name, 'campaign spec', bundled_specs)
    return parse_spec(content, source=str(path), base_dir=path.resolve().parent)


def parse_spec(text: str, *, source: str | None = None, base_dir=None) -> CampaignSpec:
    """Parse and validate spec YAML text.

    ``base_dir`` resolves a relative ``scenario`` (default: the current directory). Also validates
    the resolved scenarios of draw 0 (module docstring).
    """
    data, lines = parse_yaml(text, source)
    if data is None:
        raise E.MissingFieldError('the campaign spec is empty; required keys: ' + ', '.join(_TOP_REQUIRED)
                                  + ' and one of scenario, generator', source=source)
    ctx = ConfigContext(source, lines)
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    top = ctx.mapping(data, (), _TOP_REQUIRED, _TOP_OPTIONAL, what='a campaign spec mapping')

    name = ctx.string(top['name'], ('name',))
    if not name:
        raise ctx.error(E.InvalidValueError, ('name',), 'empty name; allowed: a non-empty string')
    description = ctx.string(top.get('description', ''), ('description',))
    runs = ctx.integer(top['runs'], ('runs',), lo=1, what='an integer number of draws >= 1')
    seed = ctx.integer(top.get('seed', 0), ('seed',), lo=0, what='an integer seed >= 0')

    if ('scenario' in top) == ('generator' in top):
        raise ctx.error(E.MissingFieldError if 'scenario' not in top else E.InvalidValueError, (),
                        'give exactly one of `scenario` (a base scenario: bundled name or file) and '
                        '`generator` (random graphs of N leaders and M followers)')
    generator = _generator(ctx, top['generator']) if 'generator' in top else None

    duration = None
    if 'duration' in top:
        duration = ctx.number(top['duration'], ('duration',), lo=0.0, lo_open=True, unit='s')
    settle_time = None
    if 'settle_time' in top:
        settle_time = ctx.number(top['settle_time'], ('settle_time',), lo=0.0, unit='s')

    scenario_file, base_mapping = None, None
    if generator is None:
        scenario_file, base_mapping = _base_scenario(ctx, top['scenario'], base)
        base_duration = float(base_mapping['duration'])
        base_settle = float(base_mapping.get('settle_time', DEFAULT_SETTLE_TIME))
    else:
        base_duration, base_settle = 60.0, 20.0
    duration = base_duration if duration is None else duration
    if settle_time is None:
        settle_time = base_settle if base_settle < duration else duration / 2.0
    elif settle_time >= duration:
        raise ctx.error(E.InvalidValueError, ('settle_time',),
                        f'settle_time {settle_time} s is not before the end of the run ({duration} s); '
                        f'allowed: [0, duration)')

    cases = _cases(ctx, top.get('cases', list(CASES)))
    success = _success(ctx, top.get('success', dict(DEFAULT_SUCCESS)))

    impairments = None
    if top.get('impairments') is not None:
        impairments = ctx.mapping(top['impairments'], ('impairments',), (),
                                  ('delay_steps', 'jitter_steps', 'loss', 'links', 'noise', 'dropouts',
                                   'delay_compensation', 'seed'),
                                  what='an impairments mapping (docs/scenario.md)')
        if 'seed' in impairments:
            raise ctx.error(E.InvalidValueError, ('impairments', 'seed'),
                            'the impairments seed is drawn for every draw from the campaign seed (so loss '
                            'and noise differ between draws); remove it, or change the campaign `seed`')
        if generator is not None and impairments.get('links'):
            raise ctx.error(E.InvalidValueError, ('impairments', 'links'),
                            'per-link impairments need a fixed graph, and the generator draws a new one per '
                            'draw; use delay_steps and loss (every link) with a generator')
        impairments = copy.deepcopy(impairments)

    n_uhs = (generator.leaders + generator.followers if generator is not None else len(base_mapping['uhs']))
    draws = _draws(ctx, top.get('draws') or {}, n_uhs)
    tilt = max((abs(float(a)) for uh in (base_mapping or {}).get('uhs', [])
                for a in ((uh.get('initial_state') or {}).get('euler') or [0.0, 0.0])[:2]), default=0.0)
    if draws.attitude_spread > 0.0 and tilt + draws.attitude_spread >= math.pi / 2:
        raise ctx.error(E.InvalidValueError, ('draws', 'attitude_spread'),
                        f'{draws.attitude_spread} rad on top of the base scenario\'s largest roll or pitch '
                        f'({tilt} rad) can reach pi/2; allowed: below {math.pi / 2 - tilt:.4f} rad')
    sweep = _sweep(ctx, top['sweep'], draws) if top.get('sweep') is not None else None

    spec = CampaignSpec(
        name=name, description=description, source=source, text=text, base_dir=base, scenario=scenario_file,
        generator=generator, runs=runs, seed=seed, duration=float(duration), settle_time=float(settle_time),
        cases=cases, success=success, impairments=impairments, sweep=sweep, draws=draws, lines=lines,
        base_mapping=base_mapping)
    _check_draw_zero(spec)
    return spec


def _range(ctx, value, path, *, lo=None, hi=None, lo_open=False, hi_open=False, unit='', integer=False):
    """Read a ``[low, high]`` list with ``low <= high`` within the given bounds."""
    if not isinstance(value, list) or len(value) != 2:
        raise ctx.error(E.WrongTypeError, path, f'expected a range [low, high]{unit_suffix(unit)}, got '
                        f'{type_name(value)} {value!r}')
    if integer:
        low, high = (ctx.integer(v, path + (i,), lo=lo) for i, v in enumerate(value))
        if hi is not None and high > hi:
            raise ctx.error(E.InvalidValueError, path + (1,), f'value {high} out of range; allowed: <= {hi}')
    else:
        low, high = (ctx.number(v, path + (i,), lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, unit=unit)
                     for i, v in enumerate(value))
    if low > high:
        raise ctx.error(E.InvalidValueError, path, f'inverted range [{value[0]}, {value[1]}]; allowed: '
                        f'[low, high] with low <= high')
    return low, high


def _base_scenario(ctx, value, base: Path):
    """(absolute file, self-contained mapping) of the base scenario ``value``."""
    name = ctx.string(value, ('scenario',))
    try:
        path, text = read_config_file(name, 'scenario', bundled_scenarios, base_dir=base)
    except E.ScenarioNotFoundError as exc:
        raise ctx.error(E.ScenarioNotFoundError, ('scenario',), exc.message) from None
    # its own errors name its own file and line
    scenario = parse_scenario(text, source=str(path), base_dir=path.resolve().parent)
    data, _ = parse_yaml(text, str(path))
    data['helicopter'] = scenario.helicopter           # a bundled name or an absolute path
    gains = scenario.gains
    if gains:
        data['gains'] = gains                          # inline: the resolved scenario stands alone
    return str(path.resolve()), data


def _generator(ctx, raw) -> GeneratorSpec:
    path = ('generator',)
    ctx.mapping(raw, path, _GENERATOR_REQUIRED, _GENERATOR_OPTIONAL, what='a generator mapping')
    n = ctx.integer(raw['leaders'], path + ('leaders',), lo=1, what='an integer number of leaders >= 1')
    m = ctx.integer(raw['followers'], path + ('followers',), lo=1, what='an integer number of followers >= 1')
    links = _range(ctx, raw.get('reference_links', [1, 1]), path + ('reference_links',), lo=1, hi=n,
                   integer=True)
    p_leader = ctx.number(raw.get('leader_edge_probability', 0.5), path + ('leader_edge_probability',),
                          lo=0.0, hi=1.0)
    p_follower = ctx.number(raw.get('follower_edge_probability', 0.5), path + ('follower_edge_probability',),
                            lo=0.0, hi=1.0)
    attempts = ctx.integer(raw.get('attempts', 100), path + ('attempts',), lo=1,
                           what='an integer number of attempts >= 1')
    weights = ctx.string(raw.get('weights', 'unit'), path + ('weights',), choices=GENERATOR_WEIGHTS)
    # Assumption 1 (docs/graph.md): every leader needs a path from the virtual leader, every
    # follower one from a leader; refuse the options under which no draw can give them
    if p_follower == 0.0:
        raise ctx.error(E.UnreachableFollowerError, path + ('follower_edge_probability',),
                        'with follower_edge_probability 0 no follower hears anyone, so none has a path from a '
                        'leader (Assumption 1); allowed: a probability in (0, 1]',
                        ids=tuple(range(n + 1, n + m + 1)))
    if p_leader == 0.0 and links[1] < n:
        raise ctx.error(E.UnreachableLeaderError, path + ('leader_edge_probability',),
                        f'with leader_edge_probability 0 only the {links[1]} leader(s) linked to the virtual '
                        f'leader are reached, never all {n} (Assumption 1); allowed: a probability > 0, or '
                        f'reference_links [{n}, {n}]')
    return GeneratorSpec(leaders=n, followers=m, reference_links=links, leader_edge_probability=p_leader,
                         follower_edge_probability=p_follower, attempts=attempts, weights=weights)


def _cases(ctx, raw) -> tuple:
    if not isinstance(raw, list) or not raw:
        raise ctx.error(E.WrongTypeError, ('cases',), f'expected a non-empty list of controller cases '
                        f'({", ".join(CASES)}), got {type_name(raw)} {raw!r}')
    cases = []
    for i, case in enumerate(raw):
        case = ctx.string(case, ('cases', i), choices=CASES)
        if case in cases:
            raise ctx.error(E.InvalidValueError, ('cases', i), f'case {case!r} is listed twice; list each once')
        cases.append(case)
    return tuple(cases)


def _success(ctx, raw) -> dict:
    ctx.mapping(raw, ('success',), (), tuple(METRIC_COLUMNS), what='a mapping metric: threshold')
    return {metric: ctx.number(value, ('success', metric)) for metric, value in raw.items()}


def _draws(ctx, raw, n_uhs: int) -> Draws:
    path = ('draws',)
    ctx.mapping(raw, path, (), _DRAW_KEYS, what='a draws mapping')
    faults = _fault_draws(ctx, raw['faults'], n_uhs) if raw.get('faults') is not None else None
    return Draws(
        position_spread=ctx.number(raw.get('position_spread', 0.0), path + ('position_spread',), lo=0.0, unit='m'),
        attitude_spread=ctx.number(raw.get('attitude_spread', 0.0), path + ('attitude_spread',), lo=0.0,
                                   hi=math.pi / 2, hi_open=True, unit='rad'),
        yaw_spread=ctx.number(raw.get('yaw_spread', 0.0), path + ('yaw_spread',), lo=0.0, unit='rad'),
        model_mismatch=(_range(ctx, raw['model_mismatch'], path + ('model_mismatch',), lo=0.0, lo_open=True)
                        if raw.get('model_mismatch') is not None else None),
        disturbance_amplitude=(_range(ctx, raw['disturbance_amplitude'], path + ('disturbance_amplitude',),
                                      lo=0.0, unit='N')
                               if raw.get('disturbance_amplitude') is not None else None),
        faults=faults)


def _fault_draws(ctx, raw, n_uhs: int) -> FaultDraws:
    path = ('draws', 'faults')
    ctx.mapping(raw, path, (), _FAULT_KEYS, what='a fault draws mapping')
    candidates = None
    if 'candidates' in raw:
        cands = raw['candidates']
        if not isinstance(cands, list) or not cands:
            raise ctx.error(E.WrongTypeError, path + ('candidates',),
                            f'expected a non-empty list of UH ids, got {type_name(cands)} {cands!r}')
        known = set(range(1, n_uhs + 1))
        for i, uh in enumerate(cands):
            ctx.uh_id(uh, path + ('candidates', i), known)
            if uh in cands[:i]:
                raise ctx.error(E.InvalidValueError, path + ('candidates', i), f'UH {uh} is listed twice')
        candidates = tuple(cands)
    n_candidates = len(candidates) if candidates is not None else n_uhs
    channels = (0, 1, 2, 3)
    if 'channels' in raw:
        chans = raw['channels']
        if not isinstance(chans, list) or not chans:
            raise ctx.error(E.WrongTypeError, path + ('channels',),
                            f'expected a non-empty list of channels, got {type_name(chans)} {chans!r}')
        channels = tuple(_channel(ctx, c, path + ('channels', i)) for i, c in enumerate(chans))
        for i, c in enumerate(channels):
            if c in channels[:i]:
                raise ctx.error(E.InvalidValueError, path + ('channels', i),
                                f'channel {CHANNEL_NAMES[c]} is listed twice')
    return FaultDraws(
        faulted_uhs=_range(ctx, raw.get('faulted_uhs', [1, 1]), path + ('faulted_uhs',), lo=0, hi=n_candidates,
                           integer=True),
        candidates=candidates, channels=channels,
        channels_per_uh=_range(ctx, raw.get('channels_per_uh', [1, 1]), path + ('channels_per_uh',), lo=1,
                               hi=len(channels), integer=True),
        rho=_range(ctx, raw.get('rho', [0.7, 0.95]), path + ('rho',), lo=0.0, hi=1.0, lo_open=True),
        bias_constant=_range(ctx, raw.get('bias_constant', [0.0, 0.0]), path + ('bias_constant',), unit='rad'),
        bias_amplitude=_range(ctx, raw.get('bias_amplitude', [0.0, 0.0]), path + ('bias_amplitude',), lo=0.0,
                              unit='rad'),
        bias_frequency=_range(ctx, raw.get('bias_frequency', [0.0, 0.0]), path + ('bias_frequency',), lo=0.0,
                              unit='rad/s'),
        onset_time=_range(ctx, raw.get('onset_time', [10.0, 10.0]), path + ('onset_time',), lo=0.0, unit='s'))


def _channel(ctx, value, path) -> int:
    """Read a channel of the fault draws: a name, or an integer index >= 0 (then 0..3)."""
    if not isinstance(value, str):
        value = ctx.integer(value, path, lo=0, what='a channel index 0..3 or name')
    return ctx.channel(value, path)


def _key_path(text: str) -> tuple:
    """``'a.b[0].c'`` -> ``('a', 'b', 0, 'c')``."""
    return tuple(m.group(1) if m.group(1) is not None else int(m.group(2)) for m in _TOKEN.finditer(text))


def _sweep(ctx, raw, draws: Draws) -> Sweep:
    path = ('sweep',)
    ctx.mapping(raw, path, ('parameter', 'values'), (), what='a sweep mapping {parameter, values}')
    parameter = ctx.string(raw['parameter'], path + ('parameter',))
    if not _KEY_PATH.match(parameter):
        raise ctx.error(E.InvalidValueError, path + ('parameter',),
                        f'{parameter!r} is not a key path; allowed: keys joined by dots, [i] for list items, e.g. '
                        f'impairments.delay_steps, model_mismatch, disturbance.amplitude[2]')
    tokens = _key_path(parameter)
    drawn = _drawn_by(tokens, draws)
    if drawn:
        raise ctx.error(E.InvalidValueError, path + ('parameter',),
                        f'{parameter} is set by {drawn}; a swept parameter must not be drawn too')
    values = raw['values']
    if not isinstance(values, list) or not values:
        raise ctx.error(E.WrongTypeError, path + ('values',),
                        f'expected a non-empty list of numbers, got {type_name(values)} {values!r}')
    for i, v in enumerate(values):
        ctx.number(v, path + ('values', i))
        if any(v == w for w in values[:i]):
            raise ctx.error(E.InvalidValueError, path + ('values', i), f'value {v!r} is listed twice')
    return Sweep(parameter=parameter, path=tokens, values=tuple(values))


def _drawn_by(tokens: tuple, draws: Draws) -> str | None:
    """Name the draws key that sets the scenario entry at ``tokens`` (None if no draw does)."""
    if tokens[:2] == ('impairments', 'seed'):
        return 'the campaign (a seed per draw)'
    if tokens[:1] == ('model_mismatch',) and draws.model_mismatch is not None:
        return 'draws.model_mismatch'
    if tokens[:2] == ('disturbance', 'amplitude') and draws.disturbance_amplitude is not None:
        return 'draws.disturbance_amplitude'
    if tokens[:1] == ('faults',) and draws.faults is not None:
        return 'draws.faults'
    if len(tokens) >= 4 and tokens[0] == 'uhs' and tokens[2] == 'initial_state':
        if tokens[3] == 'position' and draws.position_spread > 0.0:
            return 'draws.position_spread'
        if tokens[3] == 'euler' and (draws.attitude_spread > 0.0 or draws.yaw_spread > 0.0):
            return 'draws.attitude_spread / draws.yaw_spread'
    return None


# ------------------------------------------------------------------------------------------------
# Resolving a draw


def draw_generators(seed: int, draw: int) -> dict:
    """Give the independent random streams of draw ``draw``, by name.

    They are the children of ``numpy.random.default_rng([seed, draw])``, in a fixed order.
    """
    children = np.random.default_rng([seed, draw]).spawn(len(_STREAMS))
    return dict(zip(_STREAMS, children))


def scenario_file_name(spec: CampaignSpec, draw: int, sweep_index: int) -> str:
    """Name the file of a resolved scenario, relative to the campaign directory.

    ``scenarios/draw_000042.yaml`` (``..._s03.yaml`` with a sweep).
    """
    suffix = f'_s{sweep_index:02d}' if spec.sweep is not None else ''
    return f'scenarios/draw_{draw:06d}{suffix}.yaml'


def resolve_scenario(spec: CampaignSpec, draw: int, sweep_index: int = 0) -> dict:
    """Give the scenario mapping of (``draw``, ``sweep_index``).

    See the module docstring, *The resolved scenarios*. Plain data, ready for :func:`scenario_yaml`. Raises a
    :class:`~uh_topology.errors.ScenarioError` when a generated draw finds no valid graph; the
    mapping itself is validated when it is loaded.
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
    if sweep:
        _set_path(data, spec.sweep.path, spec.sweep.values[sweep_index])
    if isinstance(data.get('impairments'), dict):
        data['impairments']['seed'] = int(rng['impairments'].integers(0, 2 ** 31 - 1))
    return data


def _apply_draws(data: dict, draws: Draws, rng: dict) -> None:
    uhs = data['uhs']
    n = len(uhs)
    dp = rng['position'].uniform(-draws.position_spread, draws.position_spread, size=(n, 3))
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


def _generated_team(spec: CampaignSpec, draw: int, rng) -> dict:
    """Generate a team with a random graph that passes the topology checks.

    The team is that of :func:`uh_topology.generate.team_mapping`; the graph is redrawn at most
    ``generator.attempts`` times.
    """
    g = spec.generator
    try:
        data = team_mapping(g.leaders, g.followers, duration=spec.duration, faults=False)
    except GenerateError as exc:
        raise E.InvalidValueError(str(exc), path='duration', source=spec.source, line=spec.line('duration')) from None
    data['gains'], _ = parse_yaml(Path(data['gains']).read_text(), str(data['gains']))
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


def _check_draw_zero(spec: CampaignSpec) -> None:
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
        key = 'scenario' if spec.scenario is not None else 'generator'
        raise E.GainsFileError(f'the base scenario\'s gains or airframe cannot be used: {exc}', path=key,
                           source=spec.source, line=spec.line(key)) from None


def _at_spec_key(spec: CampaignSpec, exc: E.ScenarioError, sweep_index: int) -> E.ScenarioError:
    """``exc`` (raised by the resolved scenario of draw 0) re-raised at the spec key behind it."""
    tokens = _key_path(exc.path or '')
    sweep = spec.sweep
    key = None
    if sweep is not None and tokens[:len(sweep.path)] == sweep.path:
        # a key the scenario format does not know is the parameter's fault, not the value's
        key = ('sweep', 'parameter') if isinstance(exc, E.UnknownKeyError) else ('sweep', 'values', sweep_index)
    elif tokens[:1] == ('impairments',) and spec.impairments is not None:
        key = tokens
    elif tokens[:1] in (('duration',), ('settle_time',)) and tokens[:1] in spec.lines:
        key = tokens[:1]
    elif tokens[:1] == ('faults',) and spec.draws.faults is not None:
        key = ('draws', 'faults')
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
