"""evoscen's version: the packages' (setup.cfg, package.xml) and the CHANGELOG's newest release agree
with it (tests/test_face.py)."""

__version__ = "0.7.0"

