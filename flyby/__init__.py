"""The application: the flyby command line, the launcher of the three node processes, the in-process runner, the
operator console and the nodes' composition roots."""
