"""The bus contract: key expressions, Zenoh session settings and who may publish what, shared by every node.

Nodes talk in peer mode with explicit endpoints and multicast scouting off by default, so that two runs
can go on side by side on one machine and the same nodes run unchanged on separate hosts.

A secured bus runs Zenoh over TLS with mutual authentication: every party holds a certificate of the run's own
certificate authority whose common name is its role (``PRINCIPALS``), and Zenoh's access control lets each role
publish only on its own keys (``access_control``): only the universe drives the spacecraft's hardware (steps), only
the ground radiates (ground replies), only an operator asks the ground for a command. Plain TCP stays available for
debugging (``tls=None``), without any of this.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh
from pydantic import Field

from contracts.model import Config

NODES = ("universe", "obsw", "ground")
OPERATOR = "operator"  # the console's role: it alone may ask the ground for a command
LAUNCHER = "launcher"  # ``flyby run``'s role: it watches, and may only stop the run
PRINCIPALS = (*NODES, OPERATOR, LAUNCHER)


class Keys:
    """Key expressions of one run; every key starts with ``flyby/<run_id>``."""

    def __init__(self, run_id: str) -> None:
        if not run_id or any(c in run_id for c in "/*$?#"):
            raise ValueError(f"run id {run_id!r} must be non-empty and free of '/', '*', '$', '?', '#'")
        self.run_id = run_id
        self.root = f"flyby/{run_id}"
        self.step = f"{self.root}/obsw/step"
        self.reply = f"{self.root}/obsw/reply"
        self.ground_step = f"{self.root}/ground/step"
        self.ground_reply = f"{self.root}/ground/reply"
        self.shutdown = f"{self.root}/shutdown"
        self.status_all = f"{self.root}/status/*"
        self.alive_all = f"{self.root}/alive/*"
        self.operator = f"{self.root}/ground/operator"
        self.operator_reply = f"{self.root}/ground/operator/reply"
        self.tm_lines = f"{self.root}/ground/tm"

    def status(self, node: str) -> str:
        """Key on which ``node`` publishes its progress."""
        return f"{self.root}/status/{node}"

    def alive(self, node: str) -> str:
        """Liveliness token key of ``node``."""
        return f"{self.root}/alive/{node}"


    def publishers(self) -> dict[str, tuple[str, ...]]:
        """The keys each role may publish on."""
        return {
            "universe": (self.step, self.ground_step, self.status("universe"), self.shutdown),
            "obsw": (self.reply, self.status("obsw"), self.shutdown),
            "ground": (self.ground_reply, self.operator_reply, self.tm_lines, self.status("ground"), self.shutdown),
            OPERATOR: (self.operator,),
            LAUNCHER: (self.shutdown,),
        }


@dataclass(frozen=True)
class TlsIdentity:
    """What a party needs on a secured bus: the run's CA certificate, and its own certificate and private key (PEM)."""

    ca: Path
    cert: Path
    key: Path

    @classmethod
    def in_folder(cls, folder: Path, role: str) -> TlsIdentity:
        """The identity of ``role`` in a credentials folder (``ca.pem``, ``<role>.pem``, ``<role>.key``)."""
        return cls(folder / "ca.pem", folder / f"{role}.pem", folder / f"{role}.key")

    def missing(self) -> list[Path]:
        """The files of this identity that do not exist."""
        return [p for p in (self.ca, self.cert, self.key) if not p.is_file()]


def access_control(keys: Keys) -> dict[str, Any]:
    """Zenoh access control of a run: deny by default; each role publishes on its own keys only and declares its
    own liveliness token; every role may subscribe and watch liveliness under the run's root."""
    rules: list[dict[str, Any]] = [
        {"id": "watch", "messages": ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"],
         "flows": ["ingress", "egress"], "permission": "allow", "key_exprs": [f"{keys.root}/**"]},
        {"id": "send", "messages": ["put", "declare_subscriber", "liveliness_token"], "flows": ["egress"],
         "permission": "allow", "key_exprs": [f"{keys.root}/**"]},
    ]
    policies: list[dict[str, Any]] = [{"id": "everyone", "rules": ["watch", "send"], "subjects": ["any"]}]
    subjects: list[dict[str, Any]] = [{"id": "any", "cert_common_names": list(PRINCIPALS)}]
    for role, publishes in keys.publishers().items():
        rules.append({"id": f"publish-{role}", "messages": ["put"], "flows": ["ingress"], "permission": "allow",
                      "key_exprs": list(publishes)})
        own = [f"publish-{role}"]
        if role in NODES:
            rules.append({"id": f"alive-{role}", "messages": ["liveliness_token"], "flows": ["ingress"],
                          "permission": "allow", "key_exprs": [keys.alive(role)]})
            own.append(f"alive-{role}")
        subjects.append({"id": role, "cert_common_names": [role]})
        policies.append({"id": role, "rules": own, "subjects": [role]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


class BusConfig(Config):
    """How the nodes find each other and how long they wait before declaring a peer dead."""

    reply_timeout_s: float = Field(10.0, gt=0, description="longest wait for a peer's answer to a step, wall s")
    # a node comes up once its kernels are compiled: about 40 s for the flight software's on 2 cores after an install
    startup_timeout_s: float = Field(120.0, gt=0, description="longest wait for all nodes to come up, wall s")
    multicast_scouting: bool = Field(False, description="let Zenoh discover peers by multicast")


class EndpointError(ValueError):
    """An endpoint whose protocol does not match the bus's security (tls/ when secured, tcp/ when not)."""


def session_config(
    listen: Sequence[str] = (), connect: Sequence[str] = (), multicast_scouting: bool = False,
    tls: TlsIdentity | None = None, acl: dict[str, Any] | None = None,
) -> zenoh.Config:
    """A peer-mode Zenoh configuration with explicit endpoints; over TLS with mutual authentication as ``tls``
    (every endpoint then tls/...), and with the access control ``acl``."""
    want = "tls/" if tls is not None else "tcp/"
    wrong = [e for e in (*listen, *connect) if not e.startswith(want)]
    if wrong:
        raise EndpointError(f"endpoint {wrong[0]!r}: a {'secured' if tls else 'plain-TCP'} bus uses {want}HOST:PORT")
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "true" if multicast_scouting else "false")
    conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    # peers start in any order: retry a connection quickly rather than Zenoh's default of seconds
    conf.insert_json5("connect/retry", '{"period_init_ms": 100, "period_max_ms": 500, "period_increase_factor": 1.5}')
    if tls is not None:
        missing = tls.missing()
        if missing:
            raise FileNotFoundError(f"TLS credentials: {missing[0]} does not exist")
        # peers are identified by their certificate (mutual TLS), not by host name: the same certificates serve
        # any host layout, and access control keys on the certificate's common name
        conf.insert_json5("transport/link/tls", json.dumps({
            "root_ca_certificate": str(tls.ca), "enable_mtls": True, "verify_name_on_connect": False,
            "listen_certificate": str(tls.cert), "listen_private_key": str(tls.key),
            "connect_certificate": str(tls.cert), "connect_private_key": str(tls.key)}))
    if acl is not None:
        conf.insert_json5("access_control", json.dumps(acl))
    return conf


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])
