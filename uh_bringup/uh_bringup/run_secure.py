"""A secure team run (``run_formation.sh --secure``, docs/security.md#flying-a-secure-team).

Every node is a process of its own with its own identity: the run's environment gets ROS 2's security
variables (``ROS_SECURITY_ENABLE=true``, ``ROS_SECURITY_STRATEGY=Enforce``, ``ROS_SECURITY_KEYSTORE``) and
each node process ``ROS_SECURITY_ENCLAVE_OVERRIDE=<its fully qualified name>``; nothing else in the nodes
changes. The keystore is the one given (``--keystore DIR``, checked by ``uh-security check``), or one made
for the run in ``OUT/keystore`` (``uh-security create``). ``uh-security`` is run as a command: it stands
above this package and is not imported here.

Checked before anything starts (one line, exit status 2): a layout that puts several nodes in one process,
a domain above :data:`SECURE_MAX_DOMAIN_ID`, the rclpy backend, a ``--keystore`` that is not a keystore of
the run's scenario and safety setting, and a Python whose Cyclone DDS has no security plugins.
"""
from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

__all__ = ['SECURE_MAX_DOMAIN_ID', 'INSPECT_ENCLAVE', 'OPERATOR_ENCLAVE', 'SecureRunError', 'check_secure_args',
           'check_secure_run', 'keystore_for_run', 'security_environment', 'inspect_script']

#: Largest DDS domain of a secure run: Cyclone DDS 0.10.2 cannot parse governance or permissions naming
#: 231 or 232 (measured); uh_security.policy writes its documents for 0..this.
SECURE_MAX_DOMAIN_ID = 230
#: The read-only identity ``env.sh`` gives a second terminal (``uh``, ``ros2`` listings and echoes).
INSPECT_ENCLAVE = '/tools/inspect'
#: The operator's identity (``inject_fault.sh --secure``, ``uh param set``): may also inject faults and set parameters.
OPERATOR_ENCLAVE = '/tools/operator'
_TOOL = 'uh_security.cli'
_METADATA = 'uh_keystore.json'


class SecureRunError(ValueError):
    """Bad input of a secure run (one line; ``run_checks`` reports it as a usage error, exit status 2)."""


def check_secure_args(args, environ=None) -> None:
    """Check the options of a ``--secure`` run against each other; raise :class:`SecureRunError`."""
    environ = os.environ if environ is None else environ
    if not getattr(args, 'secure', False):
        if getattr(args, 'keystore', None) is not None:
            raise SecureRunError(f'--keystore {args.keystore} needs --secure')
        return
    if args.processes != 'per-node':
        raise SecureRunError(f'--secure with --processes {args.processes}: DDS Security gives one identity per '
                             'process, so a secure run is one process per node (--processes per-node)')
    if getattr(args, 'hosts', 'local') != 'local':
        raise SecureRunError(f'--secure with --hosts {args.hosts}: not built (docs/security.md#what-is-not-done); '
                             'allowed: --hosts local')
    given = args.domain_id if args.domain_id is not None else (
        int(environ['ROS_DOMAIN_ID']) if environ.get('ROS_DOMAIN_ID', '').isdigit() else None)
    if given is not None and not 0 <= given <= SECURE_MAX_DOMAIN_ID:
        raise SecureRunError(f'--secure on DDS domain {given}: allowed 0..{SECURE_MAX_DOMAIN_ID} (Cyclone DDS 0.10 '
                         'reads no security document naming a higher domain)')
    if environ.get('UH_ROS_WHEELS') == '1':
        raise SecureRunError('--secure with UH_ROS_WHEELS=1: a secure team runs on the Cyclone DDS backend of '
                         '.venv-secure; unset UH_ROS_WHEELS')
    if environ.get('ROS_DISTRO') and shutil.which('ros2'):
        raise SecureRunError(f'--secure with ROS 2 {environ["ROS_DISTRO"]} sourced: its nodes would start through ros2 '
                         'run on rclpy; run the secure team from a shell without ROS 2 sourced')


def _security_tool(*arguments) -> str:
    """Run ``uh-security ARGUMENTS``; return its stdout, or raise :class:`SecureRunError` with its error line."""
    done = subprocess.run([sys.executable, '-P', '-m', _TOOL, *arguments], capture_output=True, text=True)
    if done.returncode != 0:
        lines = [line for line in done.stderr.splitlines() if line.strip()]
        message = lines[-1] if lines else f'exit status {done.returncode}'
        raise SecureRunError(f'--secure: keystore {message.removeprefix("uh-security: error: ")}')
    return done.stdout


def _scenario_options(scenario, scenario_arg: str) -> list:
    return ['--scenario', scenario_arg, '--safety', 'on' if scenario.safety.enabled else 'off']


def _given(store: Path | None) -> bool:
    """Whether ``--keystore`` names something that exists and is not an empty directory (checked, not made)."""
    return store is not None and store.exists() and (not store.is_dir() or any(store.iterdir()))


def check_secure_run(args, scenario, scenario_arg: str) -> None:
    """Check a given ``--keystore`` (``uh-security check``) and this Python's binding (nothing without ``--secure``).

    A ``--keystore`` that is missing or empty is made later (:func:`keystore_for_run`).
    """
    if not getattr(args, 'secure', False):
        return
    store = Path(args.keystore) if args.keystore is not None else None
    if _given(store):
        domain = ['--domain-id', str(args.domain_id)] if args.domain_id is not None else []
        _security_tool('check', *_scenario_options(scenario, scenario_arg), '--keystore', str(store), *domain)
    try:
        version = metadata.version('cyclonedds')
    except metadata.PackageNotFoundError:
        version = 'none'
    if not version.startswith('0.10.'):
        raise SecureRunError(f'--secure needs Cyclone DDS 0.10.x with its security plugins; this Python '
                             f'({sys.executable}) has cyclonedds {version}: run scripts/run_formation.sh --secure, '
                             'which uses .venv-secure')


def keystore_for_run(args, scenario, scenario_arg: str, out: Path) -> tuple:
    """Return ``(keystore, (first, last) domain it allows)``: ``--keystore`` (made if new), else a new ``OUT/keystore``.

    The domains come from the keystore's record (``uh_keystore.json``), within 1..:data:`SECURE_MAX_DOMAIN_ID`.
    """
    store = Path(args.keystore).resolve() if args.keystore is not None else out / 'keystore'
    made = not _given(store)
    if made:
        _security_tool('create', *_scenario_options(scenario, scenario_arg), '--keystore', str(store))
    print(f'[run] keystore: {store}' + (' (made for this run by uh-security create)' if made else ''),
          file=sys.stderr)
    lo, hi = json.loads((store / _METADATA).read_text()).get('domains', (1, SECURE_MAX_DOMAIN_ID))
    return store, (max(1, lo), min(hi, SECURE_MAX_DOMAIN_ID))


def security_environment(store: Path, enclave: str | None = None) -> dict:
    """Return ROS 2's security variables for the keystore ``store`` (and the identity ``enclave``, if given)."""
    env = {'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce', 'ROS_SECURITY_KEYSTORE': str(store)}
    return {**env, 'ROS_SECURITY_ENCLAVE_OVERRIDE': enclave} if enclave else env


def inspect_script(env: dict) -> str:
    """Return the lines of ``env.sh`` that give a second terminal the read-only identity and this Python's tools."""
    lines = ['# secure run: the read-only identity, and the tools of the virtualenv with DDS Security (.venv-secure)']
    for key, value in security_environment(env['ROS_SECURITY_KEYSTORE'], INSPECT_ENCLAVE).items():
        lines.append(f'export {key}={shlex.quote(value)}')
    lines.append(f'export PATH={shlex.quote(str(Path(sys.executable).parent))}:"$PATH"')
    return '\n'.join(lines) + '\n'
