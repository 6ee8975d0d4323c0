"""evoscen runners: the in-process runner composing the cores (and, later, the node-graph launcher)."""
