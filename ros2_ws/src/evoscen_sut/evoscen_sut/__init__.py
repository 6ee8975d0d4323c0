"""evoscen systems under test: rule-based SUT models (registered with evoscen_sim.model_registry)."""
