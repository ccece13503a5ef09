"""Analysis of a run folder: loading what the nodes left, scoring it against the requirements, plots and the HTML
report. It reads the outputs of every node and imports their pure code; no node imports it."""
