"""``python -m ground``: start the ground segment node alone."""

import shutil
import sys

from flyby.nodecli import node_main
from ground.node import main


def _run(conf, sc, a):  # type: ignore[no-untyped-def]
    # the report reads the scenario from the run folder; keep a copy there when started alone
    if not (a.out / "scenario.yaml").exists():
        shutil.copyfile(a.config, a.out / "scenario.yaml")
    return main(conf, sc, a.run_id, a.out, a.timeline)


sys.exit(node_main("ground", _run))
