"""Benchmark of the telemetry archive: packets per second through decode + SQLite + tm.bin, against the link rate.

Run: .venv/bin/python bench/archive.py [--packets N] [--batch B] [--repeats R]
Traffic: housekeeping reports (215 octets) with one event and one time report every 10 packets, all distinct.
Reported: median over repeats of the decode-only rate, the archive rate (store + final flush, into a fresh
file each repeat), and the highest rate the downlink can deliver with HK-sized packets.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path
from time import perf_counter

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contracts.pus import Housekeeping, Mode, ModeChangedEvent, TimeReport, decode_tm, encode_tm  # noqa: E402
from ground.archive import Archive  # noqa: E402
from contracts.link import LinkConfig  # noqa: E402


def traffic(n: int) -> list[bytes]:
    """Return n TM packets: mostly housekeeping, with events and time reports mixed in."""
    out = []
    for i in range(n):
        obt = 1000.0 + 0.1 * i
        if i % 10 == 5:
            report = ModeChangedEvent(from_mode=Mode.STANDBY, to_mode=Mode.ACQUISITION, cause="bench")
        elif i % 10 == 9:
            report = TimeReport(obt_s=obt)
        else:
            report = Housekeeping(
                mode=Mode.NOMINAL_TRACKING,
                q=(0.1, 0.2, 0.3, 0.9273618495495703),
                rate_rad_s=(1e-3 * i, 2e-3, 3e-3),
                wheel_speed_rad_s=(10.0 + i, 20.0, 30.0),
                wheel_momentum_nms=(0.01, 0.02, 0.03),
                pointing_error_rad=1e-4,
                best_ca_obt_s=5000.0,
                best_ca_distance_km=55.0,
                best_mse_rad2=1e-8,
            )
        out.append(encode_tm(report, 0x0C1, i % 16384, obt, i % 65536))
    return out


def main() -> None:
    """Time decoding and archiving and print the rates."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--packets", type=int, default=5000)
    ap.add_argument("--batch", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    packets = traffic(args.packets)
    decode_rates, store_rates = [], []
    for _ in range(args.repeats):
        t0 = perf_counter()
        for p in packets:
            decode_tm(p)
        decode_rates.append(len(packets) / (perf_counter() - t0))
        with tempfile.TemporaryDirectory() as d:
            with Archive(Path(d) / "archive.sqlite", batch_size=args.batch) as arc:
                t0 = perf_counter()
                for i, p in enumerate(packets):
                    arc.store(p, i * 0.1)
                arc.flush()
                store_rates.append(len(packets) / (perf_counter() - t0))
                assert arc.counts()["stored"] == len(packets)
    link = LinkConfig().downlink_rate_bps / (8 * len(packets[0]))
    print(f"packets: {len(packets)}, batch {args.batch}, repeats {args.repeats}")
    print(f"decode only:        {statistics.median(decode_rates):8.0f} packets/s")
    print(f"archive (store):    {statistics.median(store_rates):8.0f} packets/s")
    print(f"downlink maximum:   {link:8.0f} packets/s ({LinkConfig().downlink_rate_bps:.0f} bit/s, "
          f"{len(packets[0])}-octet HK)")


if __name__ == "__main__":
    main()
