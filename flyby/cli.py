"""The ``flyby`` command: run, validate and inspect flyby scenarios."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from contracts.errors import ScenarioError
from contracts.exitcodes import EXIT_CONFIG
from contracts.steplog import FRAME_KEEPING
from scenario.model import Scenario, load_run_inputs, timeline_checks



def _load_or_report(path: Path) -> Scenario | None:
    """Load a scenario, or print every problem with its path in the file and return None; print its warnings."""
    try:
        scenario, timeline = load_run_inputs(path)
    except ScenarioError as err:
        print(f"{err.source}: invalid scenario ({len(err.problems)} problem(s))", file=sys.stderr)
        for line in err.problems:
            print(f"  {line}", file=sys.stderr)
        return None
    if timeline is not None:
        for line in timeline_checks(scenario, timeline)[1]:
            print(f"{path}: warning: ground.timeline_file ({scenario.ground.timeline_file}): {line}", file=sys.stderr)
    return scenario


def cmd_validate(args: argparse.Namespace) -> int:
    """Check scenario files; print every error; exit 2 if any file is invalid."""
    bad = 0
    for f in args.files:
        if _load_or_report(f) is None:
            bad += 1
        else:
            print(f"{f}: ok")
    return EXIT_CONFIG if bad else 0


def cmd_run(args: argparse.Namespace) -> int:
    """Validate, then run a scenario with the three nodes."""
    from flyby.launcher import launch

    scenario = _load_or_report(args.scenario)
    if scenario is None:
        return EXIT_CONFIG
    if args.keys is not None:
        from contracts.sdls import KeyFileError, load_key_file

        try:
            load_key_file(args.keys)
        except KeyFileError as exc:
            print(f"flyby run: --keys: {exc}", file=sys.stderr)
            return EXIT_CONFIG
    return launch(args.scenario, scenario, out=args.out, realtime=args.realtime, log_level=args.log_level,
                  insecure=args.insecure, tc_keys=args.keys, record_frames=args.record_frames, trace=args.trace)


def cmd_credentials(args: argparse.Namespace) -> int:
    """Write a set of credentials for nodes started by hand, possibly on separate hosts."""
    from contracts.sdls import KeyFileError
    from flyby.credentials import write_credentials

    try:
        write_credentials(args.folder, tc_keys=args.keys, ca_name=f"flyby CA {args.folder.name}")
    except (OSError, KeyFileError) as exc:
        print(f"flyby credentials: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    print(f"{args.folder}: ca.pem, <role>.pem and <role>.key for universe, obsw, ground, operator, launcher, and "
          "tc-keys.json; copy to each host only its own files (see the README)")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """Validate, then write the frames of perfect pointing as 8-bit PNGs and an animated GIF."""
    from contracts.clock import WallClock

    from PIL import Image

    from scenario import compose
    from universe.render import RenderRequestError, display_frame, perfect_pointing_frames, render_times_s

    scenario = _load_or_report(args.scenario)
    if scenario is None:
        return EXIT_CONFIG
    u = scenario.universe
    every_s = u.camera.frame_period_s if args.every is None else args.every
    from_s = u.start_s if args.from_s is None else args.from_s
    to_s = u.end_s if args.to_s is None else args.to_s
    try:
        times = render_times_s(from_s, to_s, every_s)
        for name, px in (("--size", args.size), ("--gif-size", args.gif_size)):
            if px < 1:
                raise RenderRequestError(f"{name} must be at least 1 px, got {px}")
    except RenderRequestError as err:
        print(f"flyby render: {err}", file=sys.stderr)
        return EXIT_CONFIG
    args.out.mkdir(parents=True, exist_ok=True)
    clock = WallClock()  # clock.py is the one module that reads the machine's time
    wall0 = clock.now()
    images = []
    for i, frame in enumerate(perfect_pointing_frames(compose.universe(scenario), times)):
        img = display_frame(frame.pixels, u.camera.bit_depth, args.size)
        Image.fromarray(img).save(args.out / f"frame_{i:05d}.png")
        # the GIF is smaller: noisy frames barely compress (~120 kB per 512 px frame)
        images.append(Image.fromarray(img).resize((args.gif_size, args.gif_size), Image.Resampling.BOX))
        print(f"\rframe {i + 1}/{len(times)}  t={frame.t_s:+.1f} s", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    gif = args.out / "render.gif"
    images[0].save(gif, save_all=True, append_images=images[1:], duration=args.gif_frame_ms, loop=0)
    print(f"{len(times)} frames of {scenario.name}, t={times[0]:+.1f}..{times[-1]:+.1f} s every {every_s:g} s, "
          f"in {clock.now() - wall0:.1f} s: {args.out}/frame_*.png and {gif}")
    return 0


def obt_epoch_note() -> str:
    """What OBT 0 is, for the XTCE time descriptions: the oscillator configuration's own words and default."""
    from universe.config import OscillatorConfig

    offset = OscillatorConfig.model_fields["initial_offset_s"]
    return (f"OBT at the scenario epoch is the scenario's universe.oscillator.initial_offset_s (default "
            f"{offset.default:,.0f} s: {offset.description}); from there OBT runs at the oscillator's rate "
            "(drift_ppm, drift_rate_ppm_per_day), so ground maps it to UTC with its time correlation (service 9).")


def cmd_dictionary(args: argparse.Namespace) -> int:
    """Print the TM/TC dictionary as Markdown, or write its telemetry as XTCE 1.2 (``--xtce FILE``)."""
    if args.xtce is None:
        from contracts.dictionary_doc import markdown

        sys.stdout.write(markdown())
        return 0
    from contracts.xtce import xtce_text

    args.xtce.write_text(xtce_text(obt_epoch_note()), encoding="utf-8")
    print(f"{args.xtce}: XTCE 1.2 of every telemetry packet of the dictionary")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """``flyby report RUN_DIR``; the report's module (matplotlib: 1.5 s of imports) loads only for it."""
    from analysis.report import cmd_report as report

    return report(args)


# sub-commands whose parsers need no more than this module's imports: ``flyby run`` starts without loading the
# flight software, the replay and Dask, which the other sub-commands' parsers import (about a second)
LIGHT_COMMANDS = frozenset({"run", "credentials", "validate", "render", "dictionary", "report"})


def build_parser(light_only: bool = False) -> argparse.ArgumentParser:
    """The argument parser of every sub-command, or of ``LIGHT_COMMANDS`` only."""
    p = argparse.ArgumentParser(prog="flyby", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scenario: universe, obsw and ground as three processes over Zenoh")
    r.add_argument("scenario", type=Path)
    r.add_argument("--out", type=Path, default=None, help="run folder (default runs/<scenario>-<UTC stamp>)")
    r.add_argument("--realtime", action="store_true", help="pace the universe to the wall clock")
    r.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    r.add_argument("--keys", type=Path, default=None, metavar="FILE",
                   help="telecommand key file to use (mode 0600; default: fresh keys for this run)")
    r.add_argument("--insecure", action="store_true",
                   help="plain-TCP bus without TLS or access control, for debugging (prints a warning)")
    r.add_argument("--record-frames", choices=FRAME_KEEPING, default=FRAME_KEEPING[0],
                   help="how the step record (obsw_steps.rec) keeps camera frames: by reference (default: a digest, "
                   "the replay renders them again from the scenario and the truth) or raw (the pixels, about 0.55 MB "
                   "a frame; replays with a build whose universe renders differently)")
    r.add_argument("--trace", action="store_true",
                   help="each node writes the time marks of its lock-step messages and work to NODE.trace.csv in the "
                   "run folder (bench/loop_trace.py prints where the loop's time goes)")
    r.set_defaults(func=cmd_run)
    cr = sub.add_parser("credentials", help="write a CA, certificates and TC keys for nodes started by hand")
    cr.add_argument("folder", type=Path, help="a new or empty folder (made private, 0700)")
    cr.add_argument("--keys", type=Path, default=None, metavar="FILE", help="copy this TC key file instead of "
                    "making fresh keys")
    cr.set_defaults(func=cmd_credentials)
    v = sub.add_parser("validate", help="check scenario files and print every error with its path")
    v.add_argument("files", type=Path, nargs="+")
    v.set_defaults(func=cmd_validate)
    d = sub.add_parser("render", help="write the frames the camera would see with perfect pointing (PNGs and a GIF)")
    d.add_argument("scenario", type=Path)
    d.add_argument("--out", type=Path, required=True, help="folder for frame_NNNNN.png and render.gif")
    d.add_argument("--every", type=float, default=None, help="s between frames (default: the camera frame period)")
    d.add_argument("--from", dest="from_s", type=float, default=None, help="first true time, s (default: run start)")
    d.add_argument("--to", dest="to_s", type=float, default=None, help="last true time, s (default: run end)")
    d.add_argument("--size", type=int, default=512, help="side of the PNG and GIF images, px")
    d.add_argument("--gif-size", type=int, default=256, help="side of the GIF images, px")
    d.add_argument("--gif-frame-ms", type=int, default=100, help="display time of each GIF frame, ms")
    d.set_defaults(func=cmd_render)
    dic = sub.add_parser("dictionary", help="print the TM/TC dictionary as Markdown, or export its telemetry as XTCE")
    dic.add_argument("--xtce", type=Path, default=None, metavar="FILE", help="write XTCE 1.2 (for Yamcs) to FILE")
    dic.set_defaults(func=cmd_dictionary)
    rep = sub.add_parser("report", help="(re)write a run folder's flyby report: report.html, report/, figures.json")
    rep.add_argument("run_dir", type=Path)
    rep.set_defaults(func=cmd_report)
    if light_only:
        return p
    from ground.tmquery import add_tm_arguments

    add_tm_arguments(sub.add_parser("tm", help="list, print or export (CSV) archived telemetry parameters of a run"))
    from flyby.campaign import add_parser as add_campaign
    from flyby.console import add_parser as add_ground_console
    from flyby.montecarlo.cli import add_parser as add_mc
    from flyby.replay import add_parser as add_replay

    add_ground_console(sub)
    add_mc(sub)
    add_replay(sub)
    add_campaign(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``flyby`` console command."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    args = build_parser(light_only=command in LIGHT_COMMANDS).parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
