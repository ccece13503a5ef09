"""Command timelines: file formats, command definitions and conversion to on-board time."""
