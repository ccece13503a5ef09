"""The bus contract: key expressions and Zenoh session settings shared by every node.

Nodes talk in peer mode with explicit endpoints and multicast scouting off by default, so that two runs
can go on side by side on one machine and the same nodes run unchanged on separate hosts.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Sequence

import zenoh
from pydantic import Field

from contracts.model import Config

NODES = ("universe", "obsw", "ground")


class Keys:
    """Key expressions of one run; every key starts with ``flyby/<run_id>``."""

    def __init__(self, run_id: str) -> None:
        if not run_id or any(c in run_id for c in "/*$?#"):
            raise ValueError(f"run id {run_id!r} must be non-empty and free of '/', '*', '$', '?', '#'")
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


class BusConfig(Config):
    """How the nodes find each other and how long they wait before declaring a peer dead."""

    reply_timeout_s: float = Field(10.0, gt=0, description="longest wait for a peer's answer to a step, wall s")
    startup_timeout_s: float = Field(30.0, gt=0, description="longest wait for all nodes to come up, wall s")
    multicast_scouting: bool = Field(False, description="let Zenoh discover peers by multicast")


def session_config(
    listen: Sequence[str] = (), connect: Sequence[str] = (), multicast_scouting: bool = False
) -> zenoh.Config:
    """A peer-mode Zenoh configuration with explicit endpoints."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "true" if multicast_scouting else "false")
    conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    # peers start in any order: retry a connection quickly rather than Zenoh's default of seconds
    conf.insert_json5("connect/retry", '{"period_init_ms": 100, "period_max_ms": 500, "period_increase_factor": 1.5}')
    return conf


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])
