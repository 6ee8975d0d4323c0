"""Error types shared by every evoscen package."""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input (config, map, bag, data file, CLI argument).

    The message is one line naming the file, the key or element (and line),
    the offending value and what is allowed. Command-line tools print it as
    ``error: <message>`` and exit with status 2.
    """
