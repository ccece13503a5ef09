"""``python -m universe``: start the universe node alone."""

import sys

from flyby.nodecli import node_main
from universe.node import main

sys.exit(node_main("universe", lambda conf, sc, a: main(conf, sc, a.run_id, a.out, a.realtime)))
