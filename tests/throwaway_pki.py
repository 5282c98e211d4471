"""A throw-away certificate authority and laboratory key for the signature tests (never reused)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import pkcs12
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID


def _name(cn: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "calflow tests"),
            x509.NameAttribute(NameOID.COMMON_NAME, cn),
        ]
    )


def make(folder: Path, password: str = "test-only") -> dict:
    """A CA (``ca.pem``), a laboratory key and certificate it issued (``lab.p12``, with the CA in
    its chain) and an unrelated CA (``other-ca.pem``), in ``folder``: their paths."""
    now = dt.datetime.now(dt.UTC)
    out = {}

    def ca(name):
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (
            x509.CertificateBuilder()
            .subject_name(_name(name))
            .issuer_name(_name(name))
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(days=1))
            .not_valid_after(now + dt.timedelta(days=30))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(
                x509.KeyUsage(False, False, False, False, False, True, True, False, False), critical=True
            )
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
            .sign(key, hashes.SHA256())
        )
        return key, cert

    ca_key, ca_cert = ca("Throw-away test CA")
    _, other = ca("Another test CA")
    lab_key = ec.generate_private_key(ec.SECP256R1())
    lab = (
        x509.CertificateBuilder()
        .subject_name(_name("Test calibration laboratory"))
        .issuer_name(ca_cert.subject)
        .public_key(lab_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(days=1))
        .not_valid_after(now + dt.timedelta(days=30))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(True, True, False, False, False, False, False, False, False), critical=True
        )
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.EMAIL_PROTECTION]), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(lab_key.public_key()), critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    out["ca"] = folder / "ca.pem"
    out["ca"].write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    out["other_ca"] = folder / "other-ca.pem"
    out["other_ca"].write_bytes(other.public_bytes(serialization.Encoding.PEM))
    out["p12"] = folder / "lab.p12"
    out["p12"].write_bytes(
        pkcs12.serialize_key_and_certificates(
            b"lab", lab_key, lab, [ca_cert], serialization.BestAvailableEncryption(password.encode())
        )
    )
    out["password"] = password
    return out
