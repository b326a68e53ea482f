"""A team's keystore in sros2's layout: a CA, one identity per node, signed governance and permissions.

Layout (that of ``ros2 security create_keystore`` and ``create_enclave``, so rmw_cyclonedds with
``ROS_SECURITY_KEYSTORE`` and an enclave finds the same files)::

    DIR/public/ca.cert.pem            the CA certificate; identity_ca.cert.pem and permissions_ca.cert.pem link to it
    DIR/private/ca.key.pem            the CA's private key; identity_ca.key.pem and permissions_ca.key.pem link to it
    DIR/enclaves/governance.xml, governance.p7s
    DIR/enclaves/<enclave path>/      cert.pem, key.pem, permissions.xml, permissions.p7s, and links to
                                      governance.p7s, identity_ca.cert.pem, permissions_ca.cert.pem
    DIR/policy.xml                    the ROS 2 access-control policy of every enclave (what a person reads)
    DIR/uh_keystore.json              the scenario, its safety setting and the enclaves it was made for

Keys are ECDSA on P-256 (prime256v1, as DDS Security's PKI-DH asks), certificates X.509 signed with
SHA-256, governance and permissions S/MIME-signed (detached, text) by the permissions CA with the
``cryptography`` package's PKCS#7 builder, as sros2 signs them. Private keys are written unencrypted
with mode 0600: how they are kept is the deployment's business (docs/security.md#what-it-does-not-cover).
"""
from __future__ import annotations

import datetime
import json
import os
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import pkcs7
from cryptography.x509.oid import NameOID

from . import policy

__all__ = ['KeystoreError', 'CA_NAME', 'VALIDITY_DAYS', 'METADATA', 'is_keystore', 'create_keystore',
           'check_keystore', 'enclave_dir', 'sign_smime', 'read_metadata']

#: Common name of the keystore's CA (sros2's default).
CA_NAME = 'sros2CA'
#: Validity of the CA and of every identity, from the moment the keystore is made (sros2's ten years).
VALIDITY_DAYS = 3650
#: The keystore's own record of what it was made for (not part of sros2's layout; sros2 ignores it).
METADATA = 'uh_keystore.json'
_PRIVATE_FILES = ('ca.key.pem', 'identity_ca.key.pem', 'permissions_ca.key.pem')
_PUBLIC_FILES = ('ca.cert.pem', 'identity_ca.cert.pem', 'permissions_ca.cert.pem')


class KeystoreError(Exception):
    """The keystore directory cannot be used (exists and is not a keystore, or cannot be written)."""


def is_keystore(path: Path) -> bool:
    """Return whether ``path`` holds a keystore (sros2's test: the CA files and the signed governance)."""
    path = Path(path)
    return (all((path / 'public' / f).is_file() for f in ('identity_ca.cert.pem', 'permissions_ca.cert.pem'))
            and all((path / 'private' / f).is_file() for f in ('identity_ca.key.pem', 'permissions_ca.key.pem'))
            and (path / 'enclaves' / 'governance.p7s').is_file())


def enclave_dir(keystore: Path, enclave: str) -> Path:
    """Return the directory of ``enclave`` (``'/uh1/controller'``) in ``keystore``."""
    return Path(keystore) / 'enclaves' / enclave.strip('/')


def read_metadata(keystore: Path) -> dict:
    """Return the keystore's :data:`METADATA` record (``{}`` for a keystore made by other tools)."""
    path = Path(keystore) / METADATA
    return json.loads(path.read_text()) if path.is_file() else {}


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def _certificate(subject: str, key, issuer: str, issuer_key, ca: bool, now: datetime.datetime) -> x509.Certificate:
    """Build a certificate of ``key``'s public half for ``subject``, signed by ``issuer_key`` (as sros2's)."""
    constraints = x509.BasicConstraints(ca=True, path_length=1) if ca else x509.BasicConstraints(ca=False,
                                                                                                  path_length=None)
    return (x509.CertificateBuilder().issuer_name(_name(issuer)).subject_name(_name(subject))
            .serial_number(x509.random_serial_number()).not_valid_before(now)
            .not_valid_after(now + datetime.timedelta(days=VALIDITY_DAYS)).public_key(key.public_key())
            .add_extension(constraints, critical=ca).sign(issuer_key, hashes.SHA256()))


def sign_smime(certificate: x509.Certificate, key, content: bytes) -> bytes:
    """Return ``content`` S/MIME-signed by ``certificate``'s ``key`` (detached, text: the form DDS Security reads)."""
    return (pkcs7.PKCS7SignatureBuilder().set_data(content).add_signer(certificate, key, hashes.SHA256())
            .sign(serialization.Encoding.SMIME, [pkcs7.PKCS7Options.Text, pkcs7.PKCS7Options.DetachedSignature]))


def _write_key(path: Path, key) -> None:
    path.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))
    path.chmod(0o600)


def _link(target: Path, link: Path) -> None:
    """Make ``link`` a relative symbolic link to ``target`` (replacing what is there)."""
    if link.is_symlink() or link.exists():
        link.unlink()
    link.symlink_to(os.path.relpath(target, link.parent))


def _make_ca(keystore: Path, now: datetime.datetime):
    """Write the CA (one for identities and permissions, as sros2 makes it); return ``(certificate, key)``."""
    key = ec.generate_private_key(ec.SECP256R1())
    certificate = _certificate(CA_NAME, key, CA_NAME, key, True, now)
    (keystore / 'public' / 'ca.cert.pem').write_bytes(certificate.public_bytes(serialization.Encoding.PEM))
    _write_key(keystore / 'private' / 'ca.key.pem', key)
    for directory, files in (('public', _PUBLIC_FILES), ('private', _PRIVATE_FILES)):
        for name in files[1:]:
            _link(keystore / directory / files[0], keystore / directory / name)
    return certificate, key


def _make_enclave(keystore: Path, grant: policy.Grant, ca, domains: policy.DomainRange, now) -> None:
    """Write ``grant``'s identity and signed permissions into its enclave directory."""
    ca_certificate, ca_key = ca
    folder = enclave_dir(keystore, grant.enclave)
    folder.mkdir(parents=True, exist_ok=True)
    key = ec.generate_private_key(ec.SECP256R1())
    certificate = _certificate(grant.enclave, key, CA_NAME, ca_key, False, now)
    (folder / 'cert.pem').write_bytes(certificate.public_bytes(serialization.Encoding.PEM))
    _write_key(folder / 'key.pem', key)
    permissions = policy.xml_text(policy.permissions_xml(
        grant, certificate.not_valid_before_utc.strftime('%Y-%m-%dT%H:%M:%S'),
        certificate.not_valid_after_utc.strftime('%Y-%m-%dT%H:%M:%S'), domains)).encode()
    (folder / 'permissions.xml').write_bytes(permissions)
    (folder / 'permissions.p7s').write_bytes(sign_smime(ca_certificate, ca_key, permissions))
    _link(keystore / 'enclaves' / 'governance.p7s', folder / 'governance.p7s')
    for name in ('identity_ca.cert.pem', 'permissions_ca.cert.pem'):
        _link(keystore / 'public' / name, folder / name)


def create_keystore(keystore: Path, grants, scenario_record: dict,
                    domains: policy.DomainRange | None = None) -> list:
    """Write a keystore for ``grants`` (:func:`uh_security.policy.team_grants`) into ``keystore``; return the enclaves.

    ``keystore`` must be missing or empty (:class:`KeystoreError` otherwise: an existing keystore is
    not overwritten, its CA would change under the identities already handed out). ``scenario_record``
    goes into :data:`METADATA` with the enclaves and the domains (default: every domain of a run).
    """
    keystore, domains = Path(keystore), domains or policy.DomainRange()
    if keystore.exists() and not keystore.is_dir():
        raise KeystoreError(f'{keystore} exists and is not a directory; give a new directory for the keystore')
    if keystore.is_dir() and any(keystore.iterdir()):
        what = 'is a keystore already' if is_keystore(keystore) else 'exists and is not a keystore'
        raise KeystoreError(f'{keystore} {what}; give a new or empty directory (an existing keystore is not '
                            'overwritten)')
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    try:
        for directory in ('public', 'private', 'enclaves'):
            (keystore / directory).mkdir(parents=True, exist_ok=True)
        (keystore / 'private').chmod(0o700)
        ca = _make_ca(keystore, now)
        governance = policy.xml_text(policy.governance_xml(domains)).encode()
        (keystore / 'enclaves' / 'governance.xml').write_bytes(governance)
        (keystore / 'enclaves' / 'governance.p7s').write_bytes(sign_smime(*ca, governance))
        for grant in grants:
            _make_enclave(keystore, grant, ca, domains, now)
        (keystore / 'policy.xml').write_text(policy.xml_text(policy.policy_xml(grants)))
        enclaves = [g.enclave for g in grants]
        record = {**scenario_record, 'domains': [domains.lo, domains.hi], 'enclaves': enclaves}
        (keystore / METADATA).write_text(json.dumps(record, indent=2) + '\n')
    except OSError as exc:
        raise KeystoreError(f'{keystore}: cannot write the keystore ({exc.strerror}); choose a directory you can '
                            'write to') from None
    return enclaves


def _describe(record: dict) -> str:
    safety = {True: 'on', False: 'off'}.get(record.get('safety'), '?')
    return f"scenario {record.get('scenario', '?')} (safety filter {safety})"


def _check_identity(keystore: Path, enclave: str, ca_certificate, now: datetime.datetime) -> None:
    """Raise :class:`KeystoreError` unless ``enclave``'s certificate is this CA's and valid at ``now``."""
    folder = enclave_dir(keystore, enclave)
    try:
        certificate = x509.load_pem_x509_certificate((folder / 'cert.pem').read_bytes())
        certificate.verify_directly_issued_by(ca_certificate)
    except OSError:
        raise KeystoreError(f'{keystore}: the identity {enclave} is missing ({folder / "cert.pem"}); make a new '
                            'keystore (uh-security create)') from None
    except (ValueError, TypeError, InvalidSignature):
        raise KeystoreError(f'{keystore}: the certificate of {enclave} is not signed by the keystore\'s CA (a '
                            'foreign certificate); make a new keystore (uh-security create)') from None
    if not certificate.not_valid_before_utc <= now <= certificate.not_valid_after_utc:
        raise KeystoreError(f'{keystore}: the certificate of {enclave} is valid '
                            f'{certificate.not_valid_before_utc:%Y-%m-%d} .. {certificate.not_valid_after_utc:%Y-%m-%d}'
                            ', not now (expired?); make a new keystore (uh-security create)')
    if not (folder / 'permissions.p7s').is_file():
        raise KeystoreError(f'{keystore}: {enclave} has no signed permissions; make a new keystore '
                            '(uh-security create)')


def check_keystore(keystore: Path, grants, scenario_record: dict, domain: int | None = None) -> dict:
    """Check that ``keystore`` was made for ``grants`` (a scenario's) and may fly on ``domain``; return its record.

    One :class:`KeystoreError` line otherwise: not a keystore, made for another scenario or safety setting
    (the names in :data:`METADATA`, and its ``policy.xml`` against the one of ``grants``: a scenario file
    changed since), documents valid on other domains, or an identity whose certificate is missing, not
    signed by the keystore's CA or not valid now (expired).
    """
    keystore = Path(keystore)
    if not is_keystore(keystore):
        raise KeystoreError(f'{keystore} exists and is not a keystore (no CA or governance); give a keystore of '
                            'uh-security create, or a new directory')
    record = read_metadata(keystore)
    wanted = {k: scenario_record[k] for k in ('scenario', 'safety')}
    if {k: record.get(k) for k in wanted} != wanted:
        raise KeystoreError(f'{keystore} is the keystore of {_describe(record)}, not of {_describe(scenario_record)}'
                            ': make one for it (uh-security create) or give no keystore')
    try:
        written = (keystore / 'policy.xml').read_text()
    except OSError:
        written = None
    if written != policy.xml_text(policy.policy_xml(grants)):
        raise KeystoreError(f'{keystore}: its policy is not the graph of {_describe(scenario_record)} (the scenario '
                            'changed since the keystore was made): make a new one (uh-security create)')
    lo, hi = record.get('domains', (0, policy.SECURE_MAX_DOMAIN_ID))
    if domain is not None and not lo <= domain <= hi:
        raise KeystoreError(f'{keystore}: its documents are valid on DDS domains {lo}..{hi}, not on {domain}')
    ca_certificate = x509.load_pem_x509_certificate((keystore / 'public' / 'identity_ca.cert.pem').read_bytes())
    now = datetime.datetime.now(datetime.timezone.utc)
    for grant in grants:
        _check_identity(keystore, grant.enclave, ca_certificate, now)
    return record
