"""evoscen_eval: metrics and evaluation of recorded runs (the bag itself: :mod:`evoscen_record`).

Import the submodules directly; this ``__init__`` imports nothing.
"""
