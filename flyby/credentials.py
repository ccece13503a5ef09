"""The credentials of a run: a certificate authority of its own, one certificate per role, and the TC key file.

``flyby run`` makes a fresh set for every run in a private temporary folder (mode 0700, every key 0600) that is
neither the run folder nor the scenario's, and deletes it when the run ends; ``flyby credentials DIR`` makes a set
to copy onto separate hosts (each host needs ``ca.pem``, its own ``<role>.pem`` and ``<role>.key``, and for the
flight software and the ground ``tc-keys.json``).

Certificates are ECDSA P-256, signed by the run's CA, valid for ``VALIDITY_DAYS``; their common name is the role the
bus's access control grants rights to (``contracts.bus.PRINCIPALS``).
"""

from __future__ import annotations

import datetime
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from contracts import sdls
from contracts.bus import PRINCIPALS
from contracts.clock import utc_now

TC_KEY_FILE = "tc-keys.json"
VALIDITY_DAYS = 30  # a run's credentials outlive any run; a longer campaign makes its own with flyby credentials
CLOCK_SKEW_S = 300  # certificates are valid from this long before they were made, for hosts whose clocks differ


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def _write_private(path: Path, data: bytes) -> None:
    """A new file readable by its owner only."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def write_credentials(folder: Path, roles: tuple[str, ...] = PRINCIPALS, tc_keys: Path | None = None,
                      ca_name: str = "flyby run CA") -> None:
    """Write a CA, a certificate and key for each role, and a TC key file (a copy of ``tc_keys``, else fresh keys)
    into ``folder``, which must be new or empty; it is made private (0700)."""
    folder.mkdir(parents=True, exist_ok=True)
    if any(folder.iterdir()):
        raise FileExistsError(f"{folder}: credentials go into a new or empty folder")
    folder.chmod(0o700)
    now = utc_now()
    start, end = now - datetime.timedelta(seconds=CLOCK_SKEW_S), now + datetime.timedelta(days=VALIDITY_DAYS)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_cert = (x509.CertificateBuilder().subject_name(_name(ca_name)).issuer_name(_name(ca_name))
               .public_key(ca_key.public_key()).serial_number(x509.random_serial_number())
               .not_valid_before(start).not_valid_after(end)
               .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
               .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                            content_commitment=False, key_encipherment=False, data_encipherment=False,
                                            key_agreement=False, encipher_only=False, decipher_only=False),
                              critical=True)
               .sign(ca_key, hashes.SHA256()))
    (folder / "ca.pem").write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    for role in roles:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (x509.CertificateBuilder().subject_name(_name(role)).issuer_name(ca_cert.subject)
                .public_key(key.public_key()).serial_number(x509.random_serial_number())
                .not_valid_before(start).not_valid_after(end)
                .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
                .add_extension(x509.SubjectAlternativeName([x509.DNSName(role)]), critical=False)
                .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                      ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
                .sign(ca_key, hashes.SHA256()))
        _write_private(folder / f"{role}.key", _key_pem(key))
        (folder / f"{role}.pem").write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    keys = sdls.load_key_file(tc_keys) if tc_keys is not None else sdls.KeyRing.generate()
    sdls.write_key_file(folder / TC_KEY_FILE, keys)
    # the CA's private key is not kept: nobody can mint another certificate for this run


@contextmanager
def run_credentials(tc_keys: Path | None = None) -> Iterator[Path]:
    """A fresh set of credentials in a private temporary folder, deleted afterwards."""
    folder = Path(tempfile.mkdtemp(prefix="flyby-credentials-"))
    try:
        write_credentials(folder, tc_keys=tc_keys)
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
