"""`flyby ground` on a live run (TLS, the operator's certificate): a good command is accepted, uplinked and verified;
a bad one is refused by ground."""

from __future__ import annotations

from pathlib import Path

import pytest

from flyby.credentials import write_credentials
from tests.integration.conftest import DATA, flyby, start_nodes, stop_nodes

pytestmark = pytest.mark.integration


def test_operator_console_on_a_live_run(tmp_path: Path) -> None:
    """set_mode SAFE is accepted and its mode change comes back in telemetry; set_mode WARP is refused."""
    creds = tmp_path / "credentials"
    write_credentials(creds)
    procs, ep, run_id = start_nodes(tmp_path, DATA / "operator.yaml", realtime=True, credentials=creds)
    console = ("ground", "--connect", ep["ground"], "--run-id", run_id, "--credentials", str(creds))
    try:
        bad = flyby(*console, "--send", "set_mode", "mode=WARP",
                    "--timeout", "60", timeout=120)
        assert bad.returncode == 1, bad.stdout + bad.stderr
        assert "REFUSED" in bad.stdout and "mode" in bad.stdout
        # watched for 20 s of the machine's time: the echo takes about 3 s of the run's, which lags under load (the full
        # suite on two cores once ended an 8 s watch with the command completed and its mode event still on its way)
        good = flyby(*console, "--send", "set_mode", "mode=SAFE",
                     "--watch", "--seconds", "20", "--timeout", "60", timeout=120)
        assert good.returncode == 0, good.stdout + good.stderr
        assert "accepted: queued SetMode" in good.stdout
        # one light time (1 s) up, execution, one light time down: the event and the verification reach ground
        assert "to_mode=<Mode.SAFE" in good.stdout or "to_mode=0" in good.stdout, good.stdout
        assert "completion ok" in good.stdout
    finally:
        stop_nodes(procs)


def test_dry_run_first_keeps_a_refused_timeline_on_the_ground(tmp_path: Path) -> None:
    """--upload-timeline with --dry-run-first rehearses from ground's current UTC; a row on an absolute tag already
    past is predicted refused, so nothing is uploaded (exit 4) and the ground node never sees the request (a row tied
    to C/A would be uploaded late and released on arrival)."""
    creds = tmp_path / "credentials"
    write_credentials(creds)
    procs, ep, run_id = start_nodes(tmp_path, DATA / "operator.yaml", realtime=True, credentials=creds)
    past = tmp_path / "past.yaml"
    past.write_text("commands:\n  - {time: OBT 1000, command: stop_imaging}\n")
    try:
        r = flyby("ground", "--connect", ep["ground"], "--run-id", run_id, "--credentials", str(creds),
                  "--upload-timeline", str(past),
                  "--dry-run-first", "--scenario", str(DATA / "operator.yaml"), "--timeout", "60", timeout=240)
        assert r.returncode == 4, r.stdout + r.stderr
        assert "dry run first, from ground's UTC" in r.stdout
        assert "REFUSED: refused by ground at upload: row 1" in r.stdout and "NOT UPLOADED" in r.stdout
    finally:
        stop_nodes(procs)
    assert "upload_timeline" not in (tmp_path / "ground.log").read_text()
