"""A run's credentials (flyby/credentials.py): certificates signed by the run's CA naming their role, private key
files, and node options that refuse a mismatched or incomplete security setting before anything runs."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from contracts import sdls
from contracts.bus import PRINCIPALS, EndpointError, Keys, access_control
from flyby.credentials import TC_KEY_FILE, run_credentials, write_credentials
from flyby.nodecli import bus_settings, node_main


def test_every_role_has_a_certificate_of_the_run_ca(tmp_path: Path) -> None:
    """Each role's certificate is signed by ca.pem, names the role, is no CA; keys and folder are owner-only."""
    folder = tmp_path / "creds"
    write_credentials(folder)
    ca = x509.load_pem_x509_certificate((folder / "ca.pem").read_bytes())
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    for role in PRINCIPALS:
        cert = x509.load_pem_x509_certificate((folder / f"{role}.pem").read_bytes())
        ca.public_key().verify(cert.signature, cert.tbs_certificate_bytes, ec.ECDSA(cert.signature_hash_algorithm))
        assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == role
        assert not cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
        assert stat.S_IMODE((folder / f"{role}.key").stat().st_mode) == 0o600
    assert not list(folder.glob("ca.key")), "the CA's private key must not be kept"
    assert sdls.load_key_file(folder / TC_KEY_FILE).active_spi == 1
    with pytest.raises(FileExistsError):
        write_credentials(folder)


def test_run_credentials_are_deleted_and_reuse_a_given_key_file(tmp_path: Path) -> None:
    """A run's folder holds a copy of the given TC key file and is gone afterwards."""
    keys = sdls.KeyRing.generate()
    sdls.write_key_file(tmp_path / "k.json", keys)
    with run_credentials(tmp_path / "k.json") as folder:
        assert sdls.load_key_file(folder / TC_KEY_FILE) == keys
    assert not folder.exists()


def test_bus_settings_refuse_what_does_not_fit(tmp_path: Path) -> None:
    """Both or neither of --credentials/--insecure, a missing certificate, or a tcp/ endpoint on TLS are refused."""
    write_credentials(tmp_path / "c", roles=("ground",))
    with pytest.raises(ValueError, match="not both"):
        bus_settings("ground", [], [], "r", tmp_path / "c", True)
    with pytest.raises(ValueError, match="not neither"):
        bus_settings("ground", [], [], "r", None, False)
    with pytest.raises(ValueError, match="obsw.pem is missing"):
        bus_settings("obsw", [], [], "r", tmp_path / "c", False)
    with pytest.raises(EndpointError, match="tls/HOST:PORT"):
        bus_settings("ground", ["tcp/127.0.0.1:1"], [], "r", tmp_path / "c", False)
    with pytest.raises(EndpointError, match="tcp/HOST:PORT"):
        bus_settings("ground", ["tls/127.0.0.1:1"], [], "r", None, True)


def test_a_node_without_its_tc_keys_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The flight software started without a TC key file stops at once with exit 2, naming the option."""
    scenario = Path(__file__).parents[1] / "integration" / "data" / "short.yaml"
    assert node_main("obsw", ["--config", str(scenario), "--insecure", "--out", str(tmp_path)]) == 2
    assert "--tc-keys FILE" in capsys.readouterr().err


def test_access_control_gives_each_role_its_own_keys() -> None:
    """Only the universe may put steps, only the ground ground replies, only the operator operator requests."""
    keys = Keys("r")
    acl = access_control(keys)
    rules = {r["id"]: r for r in acl["rules"]}
    who = {p["subjects"][0]: p["rules"] for p in acl["policies"]}
    puts = {role: {k for rid in ids if rules[rid]["messages"] == ["put"] and rules[rid]["flows"] == ["ingress"]
                   for k in rules[rid]["key_exprs"]} for role, ids in who.items()}
    assert acl["default_permission"] == "deny"
    assert {r for r, k in puts.items() if keys.step in k} == {"universe"}
    assert {r for r, k in puts.items() if keys.ground_reply in k} == {"ground"}
    assert {r for r, k in puts.items() if keys.operator in k} == {"operator"}
    assert {r for r, k in puts.items() if keys.reply in k} == {"obsw"}
