"""Fuzz the input checks: mutate valid scenarios and timelines, and count the outcomes.

Each mutated pair of files must either be refused with every problem line naming its field, or run (in process,
the first control periods) without an exception. Prints the counts of each outcome and every failure.

    .venv/bin/python bench/fuzz_inputs.py --examples 10000
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import traceback
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hypothesis import HealthCheck, given, settings  # noqa: E402

from tests.scenario.mutations import mutated_texts, outcome  # noqa: E402


class _Printed(list):
    """A list of failures that prints each one as it comes: a long campaign shows them as they happen."""

    def append(self, item: str) -> None:  # type: ignore[override]
        super().append(item)
        print("FAILED:", item, file=sys.stderr, flush=True)


def main() -> int:
    """Run the fuzz campaign; exit 1 if any example failed."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--examples", type=int, default=10_000)
    p.add_argument("--steps", type=int, default=20, help="control periods each valid run goes through")
    args = p.parse_args()
    counts: Counter[str] = Counter()
    failures: list[str] = _Printed()

    @settings(max_examples=args.examples, deadline=None, database=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(texts=mutated_texts())
    def one(texts: tuple[bytes, bytes, str]) -> None:
        with tempfile.TemporaryDirectory() as d:
            try:
                counts[outcome(Path(d), texts[0], texts[1], args.steps)] += 1
            except Exception as exc:  # noqa: BLE001 - every failure is collected and printed
                counts["FAILED"] += 1
                failures.append(f"{texts[2]}: {type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}")
        n = sum(counts.values())
        if n % 500 == 0:
            print(f"{n} examples: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), file=sys.stderr)

    one()
    total = sum(counts.values())
    print(f"{total} examples: " + ", ".join(f"{k} {v} ({100 * v / total:.1f} %)" for k, v in sorted(counts.items())))
    for f in failures[:20]:
        print("FAILED:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
