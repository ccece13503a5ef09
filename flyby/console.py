"""``flyby ground``: an operator's console on a running ground node, or on a recorded run, and the timeline dry run.

Live: it joins the run's bus (``--connect`` the ground node's endpoint, ``--run-id`` as printed by ``flyby run``),
sends one request (a command, a timeline file, a trajectory file) and prints ground's answer, and with ``--watch``
prints the housekeeping, events and verification reports as ground receives them. ``--upload-timeline FILE
--dry-run-first --scenario S`` rehearses the timeline from ground's current time first and uploads it only if the
rehearsal passes.
Recorded: ``--run DIR`` prints the same lines from a run folder's archive.
Dry run: ``--dry-run TIMELINE --scenario S [--trajectory FILE]`` rehearses a timeline before uplink
(``flyby.dryrun``): exit 0 if every command would be executed and every requirement hold, 4 if not.
"""

from __future__ import annotations

import argparse
import logging
import queue
import sys
from pathlib import Path

import yaml
import zenoh

from contracts import pus
from contracts.bus import OPERATOR, Keys
from contracts.exitcodes import ExitCode
from contracts.clock import WallClock
from contracts.errors import DecodeError
from contracts.messages import OperatorCommand, OperatorReply, Status, TmLine, decode
from contracts.runtime import Attachment

EXIT_OK, EXIT_REFUSED, EXIT_USAGE, EXIT_NO_GROUND = ExitCode.OK, ExitCode.INTERNAL, ExitCode.INVALID_INPUT, ExitCode.PEER_FAILED
EXIT_REHEARSAL_FAILED = ExitCode.CHECK_FAILED


def _key_value(items: list[str]) -> dict[str, object]:
    """``["mode=SAFE", "period_s=0.5"]`` as a mapping, values read as YAML scalars."""
    out: dict[str, object] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"argument {item!r} must be NAME=VALUE")
        k, v = item.split("=", 1)
        out[k] = yaml.safe_load(v)
    return out


def _print_line(line: TmLine, known_utc: bool = True) -> None:
    utc = f"{line.utc_s:9.2f} s" if known_utc else "        - "
    print(f"UTC {utc}  OBT {line.obt_s:14.3f} s  {line.kind:<12} {line.text}", flush=True)


def replay(run_dir: Path) -> int:
    """Print the operator lines of a recorded run, from its archive (with each packet's receipt time); from tm.bin,
    without receipt times, if the archive is damaged (then exit 2 after printing, so a script sees the damage)."""
    from ground.archive import ArchiveError
    from ground.node import tm_line
    from ground.segment import ReceivedPacket
    from ground.tmquery import TmQueryError, run_archive

    try:
        with run_archive(run_dir) as archive:
            if archive.damage:
                print(f"flyby ground: {archive.damage}", file=sys.stderr)
            for receipt, raw in archive.decoded_packets():
                header, report = pus.decode_tm(raw)
                line = tm_line(ReceivedPacket(raw, receipt, header, report, None))
                if line is not None:
                    _print_line(line, known_utc=archive.damage is None)
            damaged = archive.damage is not None
    except (TmQueryError, ArchiveError) as exc:
        print(f"flyby ground: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # the reader (head, less) has seen enough
        return EXIT_OK
    return EXIT_USAGE if damaged else EXIT_OK

def console(args: argparse.Namespace) -> int:
    """Run the ``flyby ground`` command."""
    if args.run is not None:
        return replay(args.run)
    if (args.dry_run is not None or args.dry_run_first) and args.scenario is None:
        print("flyby ground: a dry run needs --scenario S (ground's belief, link and requirements)", file=sys.stderr)
        return EXIT_USAGE
    if args.dry_run_first and not args.upload_timeline:
        print("flyby ground: --dry-run-first goes with --upload-timeline FILE", file=sys.stderr)
        return EXIT_USAGE
    if args.dry_run is not None:
        from flyby.dryrun import run_dry_run

        return run_dry_run(args.scenario, Path(args.dry_run), args.trajectory, args.jobs, fidelity=args.fidelity)
    if not args.connect:
        print("flyby ground: give --connect ENDPOINT (the ground node's) or --run RUN_DIR", file=sys.stderr)
        return EXIT_USAGE
    try:
        request = _request(args)
    except (OSError, ValueError) as exc:
        print(f"flyby ground: {exc}", file=sys.stderr)
        return EXIT_USAGE
    from flyby.nodecli import bus_settings

    try:
        conf = bus_settings(OPERATOR, [], args.connect, args.run_id, args.credentials, args.insecure)
    except ValueError as exc:
        print(f"flyby ground: {exc}", file=sys.stderr)
        return EXIT_USAGE
    keys = Keys(args.run_id)
    inbox: queue.SimpleQueue[object] = queue.SimpleQueue()
    with zenoh.open(conf) as session:

        def on(kind: type) -> object:
            def cb(sample: zenoh.Sample) -> None:
                try:
                    inbox.put(decode(kind, sample.payload.to_bytes())[0])
                except DecodeError as exc:
                    print(f"undecodable message: {exc}", file=sys.stderr)
            return cb

        subs = [session.declare_subscriber(keys.operator_reply, on(OperatorReply)),
                session.declare_subscriber(keys.tm_lines, on(TmLine)),
                session.declare_subscriber(keys.status("ground"), on(Status))]
        bus = Attachment(session, keys, "operator", WallClock(), logging.getLogger("operator"))
        bus.watch_peers()
        try:
            bus.wait_for_peers(["ground"], args.timeout)
        except Exception as exc:  # noqa: BLE001 - reported to the user as is
            print(f"flyby ground: {exc}", file=sys.stderr)
            return EXIT_NO_GROUND
        code = EXIT_OK
        if request is not None and args.dry_run_first:
            code = _rehearse_first(inbox, args)
            if code != EXIT_OK:
                return code
        if request is not None:
            reply = _wait_reply(inbox, request, bus, args.timeout, args.watch)
            if reply is None:
                print(f"flyby ground: no answer from ground within {args.timeout:g} s", file=sys.stderr)
                return EXIT_NO_GROUND
            print(("accepted: " if reply.ok else "REFUSED: ") + reply.text, flush=True)
            code = EXIT_OK if reply.ok else EXIT_REFUSED
        if args.watch:
            clock = WallClock()
            end = clock.now() + args.seconds if args.seconds else float("inf")
            try:
                while clock.now() < end:
                    try:
                        msg = inbox.get(timeout=min(0.5, max(0.0, end - clock.now())))
                    except queue.Empty:
                        continue
                    if isinstance(msg, TmLine):
                        _print_line(msg)
            except KeyboardInterrupt:
                pass
        del subs
    return code


def _rehearse_first(inbox: queue.SimpleQueue[object], args: argparse.Namespace) -> int:
    """Dry-run the timeline from ground's current UTC (its status); EXIT_OK if it passes, else why not."""
    from flyby.dryrun import run_dry_run

    clock = WallClock()
    end = clock.now() + args.timeout
    while clock.now() < end:
        try:
            msg = inbox.get(timeout=max(0.0, end - clock.now()))
        except queue.Empty:
            break
        if isinstance(msg, Status) and msg.node == "ground":
            print(f"dry run first, from ground's UTC {msg.sim_time_s:.1f} s (the upload is sent only if it passes)",
                  flush=True)
            code = run_dry_run(args.scenario, Path(args.upload_timeline), args.trajectory, args.jobs,
                               upload_utc_s=msg.sim_time_s, fidelity=args.fidelity)
            if code != EXIT_OK:
                print("NOT UPLOADED: the dry run predicts a refused command or a failed requirement", flush=True)
            return code
    print(f"flyby ground: no status from ground within {args.timeout:g} s: cannot dry-run", file=sys.stderr)
    return EXIT_NO_GROUND


def _wait_reply(inbox: queue.SimpleQueue[object], request: OperatorCommand, bus: Attachment, timeout_s: float,
                echo: bool) -> OperatorReply | None:
    """Send the request, resending each second (a fresh session's first puts may precede its routes; ground acts
    on each request number once), until ground answers or ``timeout_s`` passes."""
    clock = WallClock()
    end = clock.now() + timeout_s
    next_send = clock.now()
    while clock.now() < end:
        if clock.now() >= next_send:
            bus.publish(bus.keys.operator, request)
            next_send = clock.now() + 1.0
        try:
            msg = inbox.get(timeout=max(0.0, min(next_send, end) - clock.now()))
        except queue.Empty:
            continue
        if isinstance(msg, OperatorReply) and msg.request == request.request:
            return msg
        if echo and isinstance(msg, TmLine):
            _print_line(msg)
    return None


def _request(args: argparse.Namespace) -> OperatorCommand | None:
    """The operator request the arguments ask for, or None (watch only)."""
    number = int(WallClock().now() * 1000) % 2**31
    if args.send:
        payload = yaml.safe_dump({"command": args.send[0], "args": _key_value(args.send[1:])}).encode()
        return OperatorCommand(request=number, action="send", payload=payload, name=args.send[0])
    if args.upload_timeline:
        p = Path(args.upload_timeline)
        return OperatorCommand(request=number, action="upload_timeline", payload=p.read_bytes(), name=p.name)
    if args.upload_trajectory:
        p = Path(args.upload_trajectory)
        return OperatorCommand(request=number, action="upload_trajectory", payload=p.read_bytes(), name=p.name)
    if not args.watch:
        raise ValueError("nothing to do: give --send, --upload-timeline, --upload-trajectory or --watch")
    return None


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``flyby ground`` on the CLI's sub-parsers."""
    g = sub.add_parser("ground", help="operator console: send commands, upload files, watch housekeeping",
                       description=__doc__)
    g.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="the ground node's Zenoh endpoint, e.g. tls/127.0.0.1:7449 (printed by flyby run)")
    g.add_argument("--run-id", default="default", help="the run's identifier (printed by flyby run)")
    g.add_argument("--credentials", type=Path, default=None, metavar="DIR",
                   help="folder with ca.pem, operator.pem and operator.key (printed by flyby run)")
    g.add_argument("--insecure", action="store_true", help="the run's bus is plain TCP (flyby run --insecure)")
    g.add_argument("--run", type=Path, default=None, metavar="RUN_DIR", help="print a recorded run's lines instead")
    what = g.add_mutually_exclusive_group()
    what.add_argument("--send", nargs="+", metavar=("COMMAND", "NAME=VALUE"),
                      help="one command of the timeline dictionary (e.g. --send set_mode mode=SAFE) or a schedule request: "
                           "schedule_time_shift delta_s=2.5 [request_ids=[4,5]], schedule_delete request_ids=[4], "
                           "schedule_report [detail=true], ping, or rekey (a new TC key, made by ground)")
    what.add_argument("--upload-timeline", metavar="FILE", help="a timeline file (YAML or CSV)")
    what.add_argument("--upload-trajectory", metavar="FILE",
                      help="a trajectory file: ca_time_utc or ca_time_s, ca_distance_km, optional sigmas")
    what.add_argument("--dry-run", metavar="TIMELINE",
                      help="rehearse a timeline in process against ground's belief and its 3-sigma corners, before "
                           "uplink (needs --scenario; exit 0 pass, 4 a refused command or a failed requirement)")
    g.add_argument("--dry-run-first", action="store_true",
                   help="with --upload-timeline: rehearse it from ground's current time, upload only if it passes")
    g.add_argument("--scenario", type=Path, default=None, metavar="S",
                   help="the run's scenario: ground's belief, link and requirements for a dry run")
    g.add_argument("--trajectory", type=Path, default=None, metavar="FILE",
                   help="dry run against this trajectory file (as --upload-trajectory) instead of ground's belief")
    g.add_argument("--jobs", type=int, default=None,
                   help="dry-run cases run at a time, in separate processes (default: one per core, at most five)")
    g.add_argument("--fidelity", choices=["centroid", "image"], default="centroid",
                   help="dry run with the imaging chain's output modelled (centroid, fast) or frames rendered (image)")
    g.add_argument("--watch", action="store_true", help="print housekeeping, events and verifications as they arrive")
    g.add_argument("--seconds", type=float, default=0.0, help="stop watching after this long (0: until Ctrl-C)")
    g.add_argument("--timeout", type=float, default=15.0, help="longest wait for the ground node, s")
    g.set_defaults(func=console)
