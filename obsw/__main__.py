"""``python -m obsw``: start the obsw node alone (composed from the scenario by flyby.nodecli)."""

import sys

from flyby.nodecli import node_main

sys.exit(node_main("obsw"))
