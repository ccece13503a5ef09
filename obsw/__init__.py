"""On-board software emulator: pure flight logic plus a thin Zenoh adapter (obsw.node)."""
