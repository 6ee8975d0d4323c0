"""evoscen systems under test: the SUT plug-in interface and registry."""
