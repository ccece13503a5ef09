"""``python -m obsw``: start the on-board software node alone."""

import sys

from flyby.nodecli import node_main
from obsw.node import main

sys.exit(node_main("obsw", lambda conf, sc, a: main(conf, sc, a.run_id)))
