"""The background traffic: where it starts (``spawn``), what it is made of (``makeup``), the traffic
window that moves with the SUT (``window``) and the traffic section's parameters checked against the
road (``scenario_params``). No ROS here."""


def __getattr__(name: str):
    """A name the module ``evoscen_sim.traffic`` had in evoscen 0.4 (now :mod:`evoscen_sim.traffic.window`):
    served with a DeprecationWarning naming its new path (:mod:`evoscen_sim.moved_paths`), until 0.7.0."""
    from evoscen_sim.moved_paths import moved_attribute

    return moved_attribute(__name__, name)
