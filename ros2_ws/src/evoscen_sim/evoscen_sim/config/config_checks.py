"""The checker code of every evoscen configuration: leaf value checks and field declarators.

Each checker converts a raw value (from YAML, a ROS parameter or the command line) to the
stored type or raises :class:`_Bad`, whose ``expected`` is the text after the value in the
one-line error (``expected an integer in [1, 4]``). :func:`evoscen_sim.config.config_load.build`
walks a dataclass's fields and applies the checker each field declares in its metadata
(``{"check": checker}``): the scenario schema, the driver models' parameters and the training
configuration are all validated that way. Declare a field with :func:`number`,
:func:`integer`, :func:`flag`, :func:`text`, :func:`number_range` or :func:`names` (the
nodes' own parameters, :mod:`evoscen_sim.nodes.node_params`, are declared with them too).

Pure Python (no YAML, no numpy): the parameter dataclasses of the kernels import it.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import field
from typing import Any

from evoscen_sim.limits import MAX_DT_NS_RESIDUE, MIN_DT_S

#: BV decision policies, in the canonical order used by the ``"C:M:C"`` mix string.
POLICIES: tuple[str, ...] = ("competitive", "mutual", "cooperative")

class _Bad(Exception):
    """A value failed its check: ``expected`` says what is allowed; optionally at a sub-key."""

    def __init__(self, expected: str, subkey: str | None = None, value: Any = None,
                 allowed: tuple[str, ...] | None = None) -> None:
        super().__init__(expected)
        self.expected = expected
        self.subkey = subkey
        self.value = value
        self.allowed = allowed
        """Set when ``subkey`` is an unknown key: the keys allowed there."""


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _fmt(x: float) -> str:
    return f"{x:g}"


class _Int:
    takes_str = False

    def __init__(self, lo: int | None = None, hi: int | None = None) -> None:
        self.lo, self.hi = lo, hi
        if lo is not None and hi is not None:
            self.expected = f"expected an integer in [{lo}, {hi}]"
        elif lo is not None:
            self.expected = f"expected an integer >= {lo}"
        else:
            self.expected = "expected an integer"

    def __call__(self, value: Any) -> int:
        if not _is_int(value):
            raise _Bad(self.expected)
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            raise _Bad(self.expected)
        return int(value)


class _Float:
    takes_str = False

    def __init__(self, lo: float | None = None, hi: float | None = None, *,
                 lo_open: bool = False) -> None:
        self.lo, self.hi, self.lo_open = lo, hi, lo_open
        if lo is not None and hi is not None:
            self.expected = f"expected a number in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}]"
        elif lo is not None:
            self.expected = f"expected a number {'>' if lo_open else '>='} {_fmt(lo)}"
        else:
            self.expected = "expected a finite number"

    def __call__(self, value: Any) -> float:
        if not _is_number(value):
            raise _Bad(self.expected)
        v = float(value)
        if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
            raise _Bad(self.expected)
        if self.hi is not None and v > self.hi:
            raise _Bad(self.expected)
        return v


class _StepSize:
    """``dt_s``: in [MIN_DT_S, 1] s and a whole number of nanoseconds (the bag's stamps are
    ``step * round(dt_s * 1e9)`` ns, exact only then; see docs/input-limits.md)."""

    takes_str = False
    expected = (f"expected a number of seconds in [{_fmt(MIN_DT_S)}, 1] that is a whole number of "
                "nanoseconds (the bag's stamps are integer ns)")

    def __call__(self, value: Any) -> float:
        if not _is_number(value):
            raise _Bad(self.expected)
        v = float(value)
        if not MIN_DT_S <= v <= 1.0 or abs(v * 1e9 - round(v * 1e9)) > MAX_DT_NS_RESIDUE:
            raise _Bad(self.expected)
        return v


class _Bool:
    takes_str = False
    expected = "expected a boolean (true or false)"

    def __call__(self, value: Any) -> bool:
        if not isinstance(value, bool):
            raise _Bad(self.expected)
        return value


class _Str:
    takes_str = True

    def __init__(self, choices: Callable[[], tuple[str, ...]] | None = None, *,
                 allow_empty: bool = False) -> None:
        self.choices = choices
        self.allow_empty = allow_empty

    @property
    def expected(self) -> str:
        if self.choices is None:
            return "expected a string ('' for none)" if self.allow_empty else "expected a non-empty string"
        return "expected one of " + ", ".join(self.choices())

    def __call__(self, value: Any) -> str:
        if not isinstance(value, str) or not (value or self.allow_empty):
            raise _Bad(self.expected)
        if self.choices is not None:
            allowed = self.choices()
            if value not in allowed:
                raise _Bad(self.expected + _suggest(value, allowed))
        return value


class _Range:
    """A ``[lo, hi]`` pair of finite numbers with ``lo <= hi`` inside the given bounds
    (``hi=None``: no upper bound)."""

    takes_str = False

    def __init__(self, lo: float, hi: float | None, *, lo_open: bool = False) -> None:
        self.lo, self.hi, self.lo_open = lo, (math.inf if hi is None else hi), lo_open
        if hi is None:
            self.expected = (f"expected a list [lo, hi] of two numbers with "
                             f"{_fmt(lo)} {'<' if lo_open else '<='} lo <= hi")
        else:
            bracket = "(" if lo_open else "["
            self.expected = (f"expected a list [lo, hi] of two numbers with lo <= hi, "
                             f"both in {bracket}{_fmt(lo)}, {_fmt(hi)}]")

    def __call__(self, value: Any) -> tuple[float, float]:
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise _Bad(self.expected)
        if not all(_is_number(v) for v in value):
            raise _Bad(self.expected)
        lo, hi = float(value[0]), float(value[1])
        for v in (lo, hi):
            if v < self.lo or v > self.hi or (self.lo_open and v == self.lo):
                raise _Bad(self.expected)
        if lo > hi:
            raise _Bad(self.expected)
        return (lo, hi)


class _Numbers:
    """A list of 1..``max_len`` finite numbers, each within ``[lo, hi]``."""

    takes_str = False

    def __init__(self, lo: float, hi: float, *, max_len: int = 8) -> None:
        self.lo, self.hi, self.max_len = lo, hi, max_len
        self.expected = f"expected a list of 1 to {max_len} numbers, each in [{_fmt(lo)}, {_fmt(hi)}]"

    def __call__(self, value: Any) -> tuple[float, ...]:
        if not isinstance(value, (list, tuple)) or not 1 <= len(value) <= self.max_len:
            raise _Bad(self.expected)
        if not all(_is_number(v) and self.lo <= v <= self.hi for v in value):
            raise _Bad(self.expected)
        return tuple(float(v) for v in value)


class _MeanSd:
    """A ``[mean, sd]`` pair (``pairs``: a list of 1..8 such pairs) with mean in ``[lo, hi]`` and
    ``0 <= sd <= sd_hi``."""

    takes_str = False

    def __init__(self, lo: float, hi: float, sd_hi: float, *, pairs: bool = False) -> None:
        self.lo, self.hi, self.sd_hi, self.pairs = lo, hi, sd_hi, pairs
        one = f"[mean, sd] with mean in [{_fmt(lo)}, {_fmt(hi)}] and sd in [0, {_fmt(sd_hi)}]"
        self.expected = f"expected a list of 1 to 8 pairs {one}" if pairs else f"expected a pair {one}"

    def _one(self, value: Any) -> tuple[float, float]:
        if (not isinstance(value, (list, tuple)) or len(value) != 2 or not all(_is_number(v) for v in value)
                or not self.lo <= value[0] <= self.hi or not 0.0 <= value[1] <= self.sd_hi):
            raise _Bad(self.expected)
        return (float(value[0]), float(value[1]))

    def __call__(self, value: Any) -> Any:
        if not self.pairs:
            return self._one(value)
        if not isinstance(value, (list, tuple)) or not 1 <= len(value) <= 8:
            raise _Bad(self.expected)
        return tuple(self._one(v) for v in value)


class _Names:
    """A list of non-empty names (ROS node names), optionally from ``choices``, non-empty or
    distinct; stored as a tuple."""

    takes_str = False

    def __init__(self, choices: tuple[str, ...] | None = None, *, non_empty: bool = False,
                 distinct: bool = False) -> None:
        self.choices, self.non_empty, self.distinct = choices, non_empty, distinct
        what = ("non-empty " if non_empty else "") + "list of " + ("distinct " if distinct else "")
        if choices is None:
            self.expected = f"expected a {what}non-empty node names"
        else:
            self.expected = f"expected a {what}names from " + ", ".join(choices)

    def __call__(self, value: Any) -> tuple[str, ...]:
        if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) and x for x in value):
            raise _Bad(self.expected)
        if ((self.non_empty and not value) or (self.distinct and len(set(value)) != len(value))
                or (self.choices is not None and not set(value) <= set(self.choices))):
            raise _Bad(self.expected)
        return tuple(value)


#: The named partitions of ``bvs.nodes`` (docs/architecture.md §5, "BV nodes").
BV_NODE_MODES: tuple[str, ...] = ("by_policy", "single")
MAX_BV_NODES = 32
"""At most this many BV nodes for ``bvs.nodes: N`` (each is a process of the graph)."""


class _BvNodes:
    """``bvs.nodes``: ``by_policy``, ``single`` or a number of nodes N in [1, MAX_BV_NODES]
    (a string of digits too: a ROS parameter or an override may arrive as text)."""

    takes_str = True
    expected = (f"expected by_policy, single or a number of nodes in [1, {MAX_BV_NODES}]")

    def __call__(self, value: Any) -> str | int:
        if isinstance(value, str) and value.strip().isdigit():
            value = int(value.strip())
        if isinstance(value, str):
            if value not in BV_NODE_MODES:
                raise _Bad(self.expected + _suggest(value, BV_NODE_MODES))
            return value
        if not _is_int(value) or not 1 <= value <= MAX_BV_NODES:
            raise _Bad(self.expected)
        return int(value)


_MIX_STRING = re.compile(r"^\s*(\d+)\s*:\s*(\d+)\s*:\s*(\d+)\s*$")


class _Mix:
    """BV policy mix: a mapping policy -> non-negative int, or the string ``"C:M:C"``."""

    takes_str = True
    expected = ("expected a mapping of " + "/".join(POLICIES)
                + " to non-negative integers, or a string 'competitive:mutual:cooperative'"
                + " such as '4:3:3'")

    def __call__(self, value: Any) -> dict[str, int]:
        if isinstance(value, str):
            m = _MIX_STRING.match(value)
            if m is None:
                raise _Bad(self.expected)
            return {p: int(g) for p, g in zip(POLICIES, m.groups())}
        if not isinstance(value, Mapping):
            raise _Bad(self.expected)
        for key, v in value.items():
            if key not in POLICIES:
                raise _Bad(_unknown_text(key, POLICIES), subkey=str(key), value=None, allowed=POLICIES)
            if not _is_int(v) or v < 0:
                raise _Bad("expected a non-negative integer", subkey=key, value=v)
        return {p: int(value.get(p, 0)) for p in POLICIES}


class _MapPath:
    """``map``: a non-empty string; existence is checked after the rest (see resolve_map_path)."""

    takes_str = True
    expected = "expected a non-empty path to an OpenDRIVE (.xodr) file"

    def __call__(self, value: Any) -> str:
        if not isinstance(value, str) or not value.strip():
            raise _Bad(self.expected)
        return value


def _suggest(word: str, allowed: tuple[str, ...] | list[str]) -> str:
    close = difflib.get_close_matches(word, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _unknown_text(key: Any, allowed: tuple[str, ...] | list[str]) -> str:
    text = "unknown key; allowed keys: " + ", ".join(allowed)
    return text + (_suggest(key, allowed) if isinstance(key, str) else "")


def _check(checker: Any) -> dict[str, Any]:
    return {"check": checker}


def _section(cls: type) -> Any:
    return field(default_factory=cls, metadata={"section": cls})


# Public helpers to declare the fields of a parameter dataclass: the scenario's sections, the
# kernels' parameter sets and each driver model's parameters (``models.<name>``, see
# evoscen_sim.model_registry) are declared and validated with them.
def number(default: float, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False) -> Any:
    """A float parameter with bounds (``lo_open``: strictly above ``lo``)."""
    return field(default=default, metadata=_check(_Float(lo, hi, lo_open=lo_open)))


def integer(default: int, lo: int | None = None, hi: int | None = None) -> Any:
    """An integer parameter with bounds."""
    return field(default=default, metadata=_check(_Int(lo, hi)))


def flag(default: bool) -> Any:
    """A boolean parameter."""
    return field(default=default, metadata=_check(_Bool()))


def text(default: str, choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None, *,
         allow_empty: bool = False) -> Any:
    """A non-empty string parameter, optionally one of ``choices`` (a tuple, or a callable
    returning one at validation time, e.g. the registered SUT models); ``allow_empty``: ''
    is allowed too (an optional path)."""
    if choices is None or callable(choices):
        return field(default=default, metadata=_check(_Str(choices, allow_empty=allow_empty)))
    fixed = tuple(choices)
    return field(default=default, metadata=_check(_Str(lambda: fixed)))


def number_range(default: tuple[float, float], lo: float, hi: float, *, lo_open: bool = False) -> Any:
    """A ``[lo, hi]`` pair parameter within bounds."""
    return field(default=default, metadata=_check(_Range(lo, hi, lo_open=lo_open)))


def names(default: tuple[str, ...], choices: tuple[str, ...] | None = None, *, non_empty: bool = False,
          distinct: bool = False) -> Any:
    """A list of node names (a tuple once validated), optionally from ``choices``."""
    return field(default=default, metadata=_check(_Names(choices, non_empty=non_empty, distinct=distinct)))



def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key
