"""The campaign spec: one YAML file describing a Monte Carlo campaign of in-process team runs.

A campaign runs ``runs`` random *draws* of a team scenario, each for every controller case of
``cases`` and, with a ``sweep``, for every swept value: ``runs x len(sweep.values) x len(cases)``
runs in all. A draw is a scenario: the base scenario (or a randomly generated team) with random
initial states, actuator faults, model mismatch, disturbance and a lost UH drawn from the ranges below.

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
      losses: {uhs: [1, 2, 3, 4, 5], time: [15, 45]}   # one UH lost per draw (docs/resilience.md)
    impairments: {loss: 0.05}     # optional, copied into every resolved scenario
    resilience: {on_loss: hold}   # optional, copied into every resolved scenario
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
    containment_rms_m: 0.02, separation_violation_s: 0.0}`` (m, m, s: no pair ever closer than the
    minimum separation, docs/safety.md); a
    given mapping replaces the default (``{}``: every ``ok`` run succeeds).
``impairments``
    Optional mapping, the scenario key ``impairments`` (docs/scenario.md): delays, jitter, losses,
    noise, dropouts of the communication and the controllers' ``delay_compensation``. Copied into
    every resolved scenario (replacing any of the base scenario). Its ``seed`` is not given here:
    each draw gets its own, drawn from the draw's generator, so loss and noise patterns differ
    between draws and repeat for the same draw (the seed of impairments that come from the base
    scenario or a sweep is replaced the same way).
``resilience``
    Optional mapping, the scenario key ``resilience`` (docs/resilience.md): how the team answers a
    loss (``on_loss: reform|hold``, ``standby_edges``, ``lost_timeout``). Copied into every resolved
    scenario (replacing any of the base scenario), its values checked when draw 0's scenario is
    loaded; a list of ``standby_edges`` is refused with a generator (its graph changes per draw).
    With ``draws.losses`` it flies the same draws with another answer (``{on_loss: hold}``).
``safety``
    Optional mapping, the scenario key ``safety`` (docs/safety.md): the collision-avoidance
    filter's ``enabled`` and parameters, merged into every resolved scenario over the base
    scenario's. ``{enabled: false}`` pins the paper's law alone (the studies of the law itself);
    ``uh-campaign --safety on|off`` overrides ``enabled`` again.
``remedies``
    Optional mapping, the delay remedies of docs/delay.md#remedies, departures from the paper applied
    to every resolved scenario and every case alike: ``reference_links: all_leaders`` (replaces the
    scenario's ``reference_links``) and ``feedforward_weight: w`` in (0, 1] (replaces the gain).
    Recorded in each run's ``departures``; checked when draw 0's scenario is loaded.
``sweep``
    Optional mapping ``{parameter, values}``: every draw is run once per value, with the value
    written at ``parameter`` of the resolved scenario. ``parameter`` is a key path into the
    scenario mapping, dotted, with ``[i]`` for list items: ``impairments.delay_steps``,
    ``impairments.loss``, ``model_mismatch``, ``disturbance.amplitude[2]``,
    ``uhs[0].initial_state.omega[0]``, ``resilience.lost_timeout``. Missing mappings on the way are
    created (a sweep of ``impairments.loss`` needs no ``impairments`` key). ``values``: a non-empty
    list of numbers without repeats. A parameter the draws set (``model_mismatch`` with
    ``draws.model_mismatch``, ``faults...`` with ``draws.faults``, ``events...`` with
    ``draws.losses``, ``disturbance.amplitude`` with ``draws.disturbance_amplitude``, initial
    positions or attitudes with a spread) or ``impairments.seed`` cannot be swept.
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
``min_initial_separation``
    m, >= 0, default 0 (no condition): the positions are drawn again (from the same stream, at most
    1000 times) until every pair starts at least this far apart, hub to hub (docs/safety.md).
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

``losses``
    Mapping; when given, every draw loses one UH (docs/resilience.md): the resolved scenario's
    ``events`` (replacing the base scenario's) is ``[{time, uh, kind: lost}]``. Keys:

    ``time`` (required)
        Range, s, within (0, duration): the time is drawn uniformly in it, then rounded to the
        nearest control step (``dt``) within the range; the range must hold one.
    ``uhs``
        List of UH ids without repeats, default every UH: the lost UH is drawn uniformly among them.
    ``kind``
        ``lost`` (default) or ``stuck``: the drawn UH's actuator of a channel drawn uniformly among
        ``channels`` sticks where it is instead (``[{time, uh, kind: stuck, channel}]``;
        docs/resilience.md#leaving-the-team).
    ``channels``
        List of channels without repeats (names or 0..3), default all four; only with ``kind: stuck``.

    The loss has a stream of its own, so adding ``losses`` to a spec leaves every other draw's
    values as they were; ``resilience`` (above) says how the team answers.

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
scenario, then duration and settle time, the draws (a drawn loss as ``events``), the impairments
and the resilience, then the sweep value, the impairments' seed, ``safety`` and ``remedies``. It
names the scenario ``<name>_draw<i>[_s<j>]``, holds the gains inline and the helicopter as a
bundled name or an absolute path, so the YAML written by :func:`scenario_yaml` loads on its own
with :func:`uh_topology.scenario.load_scenario`.

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

import yaml

from uh_controller_node.gains import CASES
from uh_team.campaign_store import METRIC_COLUMNS
from uh_topology import errors as E
from uh_topology import scenario_keys
from uh_topology.generate import team_mapping
from uh_topology.scenario import bundled_scenarios, parse_scenario
from uh_topology.scenario_keys import key_named
from uh_topology.schema import CONFIG_DIR, ConfigContext, parse_yaml, read_config_file, type_name

from .draws import GENERATOR_WEIGHTS, Draws, FaultDraws, GeneratorSpec, LossDraws, read_draws, read_generator
from .resolve import check_draw_zero, draw_generators, key_path, resolve_scenario, scenario_file_name, scenario_yaml

__all__ = ['CampaignSpec', 'Draws', 'FaultDraws', 'LossDraws', 'GeneratorSpec', 'Sweep', 'load_spec', 'parse_spec',
           'bundled_specs', 'resolve_scenario', 'scenario_yaml', 'scenario_file_name', 'draw_generators',
           'DEFAULT_SUCCESS', 'BUNDLED_PREFIX', 'GENERATOR_WEIGHTS']

#: Bundled specs are ``uh_topology/config/campaign_*.yaml``.
BUNDLED_PREFIX = 'campaign_'

#: Default success thresholds: metric -> largest value that still succeeds (m).
DEFAULT_SUCCESS = {'formation_rms_m': 0.05, 'containment_rms_m': 0.02, 'separation_violation_s': 0.0}

_TOP_REQUIRED = ('name', 'runs')
_TOP_OPTIONAL = ('description', 'scenario', 'generator', 'seed', 'duration', 'settle_time', 'cases',
                 'success', 'impairments', 'safety', 'remedies', 'sweep', 'draws', 'resilience')
#: The keys of ``remedies`` (docs/delay.md#remedies).
REMEDY_KEYS = ('reference_links', 'feedforward_weight')
_KEY_PATH = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*|\[\d+\])*\Z')


# ------------------------------------------------------------------------------------------------
# Plain validated data


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
    resilience : dict or None
        The ``resilience`` mapping copied into every resolved scenario.
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
    safety: dict | None
    sweep: Sweep | None
    draws: Draws
    runs_override: int | None = None
    safety_override: bool | None = None
    remedies: dict | None = None
    resilience: dict | None = None
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
        editing the scenario or gains file is a new campaign) and of the ``--runs`` and ``--safety``
        overrides, if any.
        """
        h = hashlib.sha256(self.text.encode())
        if self.base_mapping is not None:
            h.update(b'\n' + yaml.safe_dump(self.base_mapping, sort_keys=True).encode())
        if self.runs_override is not None:
            h.update(f'\n--runs {self.runs_override}'.encode())
        if self.safety_override is not None:
            h.update(f'\n--safety {"on" if self.safety_override else "off"}'.encode())
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

    def with_safety(self, enabled: bool | None) -> 'CampaignSpec':
        """Give the spec whose every scenario has ``safety.enabled = enabled`` (``--safety on|off``; None: as is).

        Part of the digest: a campaign with the filter on is not resumed into one with it off.
        """
        if enabled is None:
            return self
        spec = replace(self, safety_override=bool(enabled))
        check_draw_zero(spec)
        return spec

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
    generator = read_generator(ctx, top['generator']) if 'generator' in top else None

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
        base_settle = float(base_mapping.get('settle_time',
                                             key_named(scenario_keys.SCENARIO_KEYS, 'settle_time').default))
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

    impairments = _impairments(ctx, top['impairments'], generator) if top.get('impairments') is not None else None
    safety = None
    if top.get('safety') is not None:   # its keys and values are checked when draw 0's scenario is loaded
        safety = dict(ctx.mapping(top['safety'], ('safety',), (), [k.name for k in scenario_keys.SAFETY_KEYS],
                                  what='a safety mapping (docs/safety.md)'))

    remedies = None
    if top.get('remedies') is not None:   # their values are checked when draw 0's scenario is loaded
        remedies = dict(ctx.mapping(top['remedies'], ('remedies',), (), REMEDY_KEYS,
                                    what='a remedies mapping (docs/delay.md#remedies)'))
    resilience = _resilience(ctx, top['resilience'], generator) if top.get('resilience') is not None else None
    n_uhs = (generator.leaders + generator.followers if generator is not None else len(base_mapping['uhs']))
    dt = float((base_mapping or team_mapping(1, 1, faults=False))['dt'])
    draws = read_draws(ctx, top.get('draws') or {}, n_uhs, duration=float(duration), dt=dt)
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
        cases=cases, success=success, impairments=impairments, safety=safety, sweep=sweep, draws=draws, lines=lines,
        base_mapping=base_mapping, remedies=remedies, resilience=resilience)
    check_draw_zero(spec)
    return spec


def _impairments(ctx, raw, generator) -> dict:
    """Check the ``impairments`` mapping a campaign copies into its scenarios; return a copy.

    Its keys are the scenario's (:data:`uh_topology.scenario_keys.IMPAIRMENT_KEYS`) but those the
    campaign draws itself (the seed); the values are checked with the resolved scenario of draw 0.
    """
    table = scenario_keys.IMPAIRMENT_KEYS
    drawn = [key.name for key in table if key.drawn_by_campaign]
    ctx.mapping(raw, ('impairments',), (), [key.name for key in table if not key.drawn_by_campaign] + drawn,
                what='an impairments mapping (docs/scenario.md)')
    for name in drawn:
        if name in raw:
            raise ctx.error(E.InvalidValueError, ('impairments', name),
                            f'the impairments {name} is drawn for every draw from the campaign seed (so loss '
                            'and noise differ between draws); remove it, or change the campaign `seed`')
    if generator is not None and raw.get('links'):
        raise ctx.error(E.InvalidValueError, ('impairments', 'links'),
                        'per-link impairments need a fixed graph, and the generator draws a new one per '
                        'draw; use delay_steps and loss (every link) with a generator')
    return copy.deepcopy(raw)


def _resilience(ctx, raw, generator) -> dict:
    """Check the ``resilience`` mapping a campaign copies into its scenarios; return a copy.

    Its keys are the scenario's (:data:`uh_topology.scenario_keys.RESILIENCE_KEYS`); the values are
    checked with the resolved scenario of draw 0.
    """
    ctx.mapping(raw, ('resilience',), (), [key.name for key in scenario_keys.RESILIENCE_KEYS],
                what='a resilience mapping (docs/resilience.md)')
    if generator is not None and isinstance(raw.get('standby_edges'), list):
        raise ctx.error(E.InvalidValueError, ('resilience', 'standby_edges'),
                        'a list of standby edges needs a fixed graph, and the generator draws a new one per '
                        'draw; use bypass or none with a generator')
    return copy.deepcopy(raw)


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


def _sweep(ctx, raw, draws: Draws) -> Sweep:
    path = ('sweep',)
    ctx.mapping(raw, path, ('parameter', 'values'), (), what='a sweep mapping {parameter, values}')
    parameter = ctx.string(raw['parameter'], path + ('parameter',))
    if not _KEY_PATH.match(parameter):
        raise ctx.error(E.InvalidValueError, path + ('parameter',),
                        f'{parameter!r} is not a key path; allowed: keys joined by dots, [i] for list items, e.g. '
                        f'impairments.delay_steps, model_mismatch, disturbance.amplitude[2]')
    tokens = key_path(parameter)
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
    drawn = {key.name for key in scenario_keys.IMPAIRMENT_KEYS if key.drawn_by_campaign}
    if tokens[:1] == ('impairments',) and len(tokens) > 1 and tokens[1] in drawn:
        return 'the campaign (a seed per draw)'
    if tokens[:1] == ('model_mismatch',) and draws.model_mismatch is not None:
        return 'draws.model_mismatch'
    if tokens[:2] == ('disturbance', 'amplitude') and draws.disturbance_amplitude is not None:
        return 'draws.disturbance_amplitude'
    if tokens[:1] == ('faults',) and draws.faults is not None:
        return 'draws.faults'
    if tokens[:1] == ('events',) and draws.losses is not None:
        return 'draws.losses'
    if len(tokens) >= 4 and tokens[0] == 'uhs' and tokens[2] == 'initial_state':
        if tokens[3] == 'position' and draws.position_spread > 0.0:
            return 'draws.position_spread'
        if tokens[3] == 'euler' and (draws.attitude_spread > 0.0 or draws.yaw_spread > 0.0):
            return 'draws.attitude_spread / draws.yaw_spread'
    return None
