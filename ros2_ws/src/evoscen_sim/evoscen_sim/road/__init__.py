"""The road: the OpenDRIVE reader, the vectorised road model built on it and its compiled queries."""


def __getattr__(name: str):
    """A name this module had in evoscen 0.4 and that moved: served with a DeprecationWarning naming its
    new path (:mod:`evoscen_sim.moved_paths`), until 0.7.0."""
    from evoscen_sim.moved_paths import moved_attribute

    return moved_attribute(__name__, name)
