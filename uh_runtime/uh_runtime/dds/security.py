"""DDS Security of the Cyclone DDS backend's participant, from ROS 2's security variables (docs/security.md).

As rcl and rmw_cyclonedds read them: with ``ROS_SECURITY_ENABLE=true`` a process's participant takes
the identity of its *enclave* in the keystore ``ROS_SECURITY_KEYSTORE`` (sros2's layout; made by
``uh-security create``): the enclave is ``ROS_SECURITY_ENCLAVE_OVERRIDE``, else the ``--ros-args
--enclave`` of the process, else ``/``, and its folder ``<keystore>/enclaves/<enclave>`` holds the six
files of :data:`ENCLAVE_FILES`. They go to the participant as the DDS Security properties ``dds.sec.*``
(QoS properties, one identity per participant and so per process), with Cyclone DDS's three plugin
libraries. ``ROS_SECURITY_STRATEGY=Enforce`` makes a missing file an error; otherwise (rcl's default,
``Permissive``) the participant then runs without security and the process says so once.

Unset or any other value of ``ROS_SECURITY_ENABLE``: no property, the participant is what it always
was. The plugins exist in Debian's Cyclone DDS 0.10.2 (the binding of requirements-secure.txt, in
``.venv-secure``), not in PyPI's 11.0.1 wheel; the participant's creation then fails with
:data:`NO_PLUGINS_HINT`.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ['ENABLE_VARIABLE', 'KEYSTORE_VARIABLE', 'ENCLAVE_OVERRIDE_VARIABLE', 'STRATEGY_VARIABLE',
           'ENCLAVE_FILES', 'PLUGINS', 'NO_PLUGINS_HINT', 'SecurityConfigError', 'enabled', 'enclave_of',
           'enclave_directory', 'participant_properties', 'properties_from_environment', 'create_participant']

ENABLE_VARIABLE = 'ROS_SECURITY_ENABLE'
KEYSTORE_VARIABLE = 'ROS_SECURITY_KEYSTORE'
ENCLAVE_OVERRIDE_VARIABLE = 'ROS_SECURITY_ENCLAVE_OVERRIDE'
STRATEGY_VARIABLE = 'ROS_SECURITY_STRATEGY'
#: DDS Security property -> file of the enclave's folder (what rmw_cyclonedds sets from the same keystore).
ENCLAVE_FILES = {
    'dds.sec.auth.identity_ca': 'identity_ca.cert.pem',
    'dds.sec.auth.identity_certificate': 'cert.pem',
    'dds.sec.auth.private_key': 'key.pem',
    'dds.sec.access.permissions_ca': 'permissions_ca.cert.pem',
    'dds.sec.access.governance': 'governance.p7s',
    'dds.sec.access.permissions': 'permissions.p7s',
}
#: Cyclone DDS's plugins: (property prefix, library, init function, finalize function).
PLUGINS = (('dds.sec.auth', 'dds_security_auth', 'init_authentication', 'finalize_authentication'),
           ('dds.sec.access', 'dds_security_ac', 'init_access_control', 'finalize_access_control'),
           ('dds.sec.crypto', 'dds_security_crypto', 'init_crypto', 'finalize_crypto'))
#: What to do when a secure participant cannot be made (no plugins in this Cyclone DDS, or a document refused).
NO_PLUGINS_HINT = ('a secure participant needs Cyclone DDS 0.10.x with its security plugins and a keystore whose '
                   'files it accepts: run with .venv-secure (scripts/_venv_secure.sh) and a keystore of '
                   'uh-security create (docs/security.md)')


class SecurityConfigError(RuntimeError):
    """``ROS_SECURITY_ENABLE=true`` with a keystore or enclave that cannot be used under ``Enforce``."""


def enabled(env=None) -> bool:
    """Return whether ``ROS_SECURITY_ENABLE`` is ``true`` (rcl's test, case-sensitive) in ``env`` (the process's)."""
    return (os.environ if env is None else env).get(ENABLE_VARIABLE) == 'true'


def enclave_of(argument_enclave: str | None, env=None) -> str:
    """Return the enclave of a process: ``ROS_SECURITY_ENCLAVE_OVERRIDE``, else its ``--enclave``, else ``/``."""
    env = os.environ if env is None else env
    return env.get(ENCLAVE_OVERRIDE_VARIABLE) or argument_enclave or '/'


def enclave_directory(keystore, enclave: str) -> Path:
    """Return the folder of ``enclave`` in ``keystore`` (``<keystore>/enclaves/<enclave>``)."""
    return Path(keystore) / 'enclaves' / enclave.strip('/')


def participant_properties(folder) -> list:
    """Return the ``[(name, value)]`` DDS Security properties of a participant with the identity in ``folder``.

    The six files of :data:`ENCLAVE_FILES` as ``file:`` URIs of their absolute paths, and the three
    plugins of :data:`PLUGINS`. :class:`SecurityConfigError` naming the first file that is missing.
    """
    folder = Path(folder).absolute()
    properties = []
    for name, file in ENCLAVE_FILES.items():
        path = folder / file
        if not path.is_file():
            raise SecurityConfigError(f'{path} is missing: the enclave {folder} is not one of a keystore '
                                      '(uh-security create makes one per node)')
        properties.append((name, f'file:{path}'))
    for prefix, library, init, finalize in PLUGINS:
        properties += [(f'{prefix}.library.path', library), (f'{prefix}.library.init', init),
                       (f'{prefix}.library.finalize', finalize)]
    return properties


def properties_from_environment(argument_enclave: str | None = None, env=None) -> list:
    """Return the DDS Security properties the environment asks for (``[]`` when security is not enabled).

    ``ROS_SECURITY_ENABLE=true`` without a keystore, or with an enclave whose files are missing, is a
    :class:`SecurityConfigError` under ``ROS_SECURITY_STRATEGY=Enforce`` and a warning on stderr (no
    security) otherwise, as in rcl.
    """
    env = os.environ if env is None else env
    if not enabled(env):
        return []
    enclave = enclave_of(argument_enclave, env)
    keystore = env.get(KEYSTORE_VARIABLE, '')
    try:
        if not keystore:
            raise SecurityConfigError(f'{ENABLE_VARIABLE}=true but {KEYSTORE_VARIABLE} is not set: give the '
                                      'keystore directory (uh-security create makes one)')
        return participant_properties(enclave_directory(keystore, enclave))
    except SecurityConfigError as exc:
        if env.get(STRATEGY_VARIABLE) == 'Enforce':
            raise
        print(f'[WARN] security not applied ({STRATEGY_VARIABLE} is not Enforce): {exc}', file=sys.stderr)
        return []


def create_participant(domain_id: int, argument_enclave: str | None = None, env=None):
    """Create the process's DDS participant on ``domain_id``, secure when the environment asks for it.

    USER_DATA ``enclave=<enclave>;`` as rmw_cyclonedds puts it (``argument_enclave`` or ``/`` without
    security); with ``ROS_SECURITY_ENABLE=true`` the enclave of :func:`enclave_of` and its identity's
    properties (:func:`properties_from_environment`). A secure participant this Cyclone DDS cannot make
    is a :class:`SecurityConfigError` saying what is needed (:data:`NO_PLUGINS_HINT`).
    """
    from cyclonedds.core import DDSException
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.qos import Policy, Qos
    properties = properties_from_environment(argument_enclave, env)
    enclave = enclave_of(argument_enclave, env) if properties else (argument_enclave or '/')
    qos = Qos(Policy.Userdata(f'enclave={enclave};'.encode()), *(Policy.Property(k, v) for k, v in properties))
    if not properties:
        return DomainParticipant(int(domain_id), qos=qos)
    try:
        return DomainParticipant(int(domain_id), qos=qos)
    except DDSException as exc:
        raise SecurityConfigError(f'enclave {enclave}: the secure participant was refused ({exc}); '
                                  f'{NO_PLUGINS_HINT}') from None
