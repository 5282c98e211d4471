"""Signatures a reader can check: the PDF as PAdES (pyHanko), the DCC as XAdES (signxml).

The laboratory's key and certificate come in one PKCS#12 file, named by the environment
variable ``CALFLOW_SIGNING_KEY`` or the configuration's ``laboratory.signing_key`` (the
variable wins); its password, if any, is the variable ``CALFLOW_SIGNING_PASSWORD``. The key
is never part of the project: a key file inside the project folder is refused. Without a
key the documents are written unsigned and say so on every page.

* PDF: a PAdES baseline signature (ETSI EN 319 142, sub-filter ``ETSI.CAdES.detached``) in a
  signature field, over the whole document, with the signer's certificate chain embedded.
* DCC: an enveloped XAdES signature (ETSI EN 319 132, signxml's ``XAdESSigner``) over the
  whole document, placed in ``dcc:comment`` — the one element of DCC 3.1.2 that admits
  foreign content, so the signed DCC stays valid against the schema.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from calflow.errors import ConfigError

KEY_ENV = "CALFLOW_SIGNING_KEY"
PASSWORD_ENV = "CALFLOW_SIGNING_PASSWORD"
DS = "http://www.w3.org/2000/09/xmldsig#"


@dataclass(frozen=True)
class Key:
    """A laboratory's signing key: the private key, its certificate and the chain above it."""

    path: Path
    private_key: object
    certificate: object
    chain: tuple

    @property
    def signer_name(self) -> str:
        """The certificate's subject, as the documents name the signer."""
        return self.certificate.subject.rfc4514_string()


def key_path(laboratory: dict, project: Path | None = None) -> Path | None:
    """The PKCS#12 file to sign with (module notes), or None; refused in one line when it
    does not exist or lies inside the project folder ``project`` (default: the current one)."""
    given = os.environ.get(KEY_ENV) or (laboratory or {}).get("signing_key")
    if not given:
        return None
    source = f"${KEY_ENV}" if os.environ.get(KEY_ENV) else "config/config.yaml: key 'laboratory.signing_key'"
    path = Path(given).expanduser().resolve()
    if not path.is_file():
        raise ConfigError(f"{source}: expected a PKCS#12 file, got {given!r} (no such file)")
    root = (project or Path.cwd()).resolve()
    if path.is_relative_to(root):
        raise ConfigError(
            f"{source}: the signing key {given!r} lies inside the project folder {root}; "
            "expected it outside (a key is never part of a repository)"
        )
    return path


def load(path: Path) -> Key:
    """The key, certificate and chain of a PKCS#12 file; refused in one line when unreadable."""
    from cryptography.hazmat.primitives.serialization import pkcs12

    password = os.environ.get(PASSWORD_ENV)
    try:
        key, cert, extra = pkcs12.load_key_and_certificates(
            path.read_bytes(), password.encode() if password else None
        )
    except (ValueError, TypeError) as exc:
        raise ConfigError(
            f"{path}: expected a PKCS#12 key and certificate readable with ${PASSWORD_ENV} ({exc})"
        ) from None
    if key is None or cert is None:
        raise ConfigError(f"{path}: expected a PKCS#12 file holding a private key and its certificate")
    return Key(path, key, cert, tuple(extra or ()))


def sign_pdf(pdf: bytes, key: Key) -> bytes:
    """``pdf`` with a PAdES signature of ``key`` over the whole document."""
    from io import BytesIO

    from pyhanko.pdf_utils.incremental_writer import IncrementalPdfFileWriter
    from pyhanko.sign import signers
    from pyhanko.sign.fields import SigSeedSubFilter

    signer = signers.SimpleSigner.load_pkcs12(
        str(key.path), passphrase=(os.environ.get(PASSWORD_ENV) or "").encode() or None
    )
    if signer is None:
        raise ConfigError(f"{key.path}: pyHanko could not read the PKCS#12 file")
    meta = signers.PdfSignatureMetadata(
        field_name="CalibrationLaboratory", subfilter=SigSeedSubFilter.PADES, md_algorithm="sha256"
    )
    out = BytesIO()
    signers.sign_pdf(IncrementalPdfFileWriter(BytesIO(pdf)), meta, signer=signer, output=out)
    return out.getvalue()


def sign_xml(xml: bytes, key: Key) -> bytes:
    """``xml`` (a DCC) with an enveloped XAdES signature of ``key`` in its ``dcc:comment``."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from lxml import etree
    from signxml import SignatureMethod, methods
    from signxml.xades import XAdESSigner

    from calflow.certificate.dcc import DCC

    root = etree.fromstring(xml)
    comment = root.find(f"{{{DCC}}}comment")
    if comment is None:
        comment = etree.Element(f"{{{DCC}}}comment")
        after = root.find(f"{{{DCC}}}measurementResults")
        after.addnext(comment)
    etree.SubElement(comment, f"{{{DS}}}Signature", Id="placeholder")
    pem = [c.public_bytes(serialization.Encoding.PEM) for c in (key.certificate, *key.chain)]
    algorithm = (
        SignatureMethod.ECDSA_SHA256
        if isinstance(key.private_key, ec.EllipticCurvePrivateKey)
        else SignatureMethod.RSA_SHA256
    )
    signer = XAdESSigner(method=methods.enveloped, signature_algorithm=algorithm)
    signed = signer.sign(root, key=key.private_key, cert=b"".join(pem).decode())
    return etree.tostring(signed, xml_declaration=True, encoding="UTF-8")
