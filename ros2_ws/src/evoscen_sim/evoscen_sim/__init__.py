"""evoscen simulation core: OpenDRIVE road, vehicle dynamics, low-level PID control, collision, re-entry and the world step."""
