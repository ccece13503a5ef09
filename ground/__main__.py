"""``python -m ground``: start the ground segment node alone."""

import sys

from flyby.nodecli import node_main
from ground.node import main

sys.exit(node_main("ground", lambda conf, sc, a: main(conf, sc, a.run_id, a.out, a.timeline)))
