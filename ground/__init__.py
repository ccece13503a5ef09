"""Ground segment: uploads, telemetry archive and reports."""
