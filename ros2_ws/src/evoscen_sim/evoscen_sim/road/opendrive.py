"""Strict reader for the subset of OpenDRIVE 1.6 that evoscen uses.

The parser reads an ``.xodr`` file with :mod:`xml.parsers.expat` (stdlib), so every element keeps the
line number it starts on, and turns it into frozen dataclasses (:class:`OpenDriveMap`). It knows
nothing about simulation; :mod:`evoscen_sim.road.road_model` builds the vectorised road model on top of it.

Supported elements (OpenDRIVE 1.6 names)
----------------------------------------
``OpenDRIVE`` > ``header`` (``geoReference`` text kept), exactly one ``road``.
``road`` > ``link`` (``predecessor``/``successor``: kept, not followed), ``type`` (with an optional
``speed``), ``planView`` > ``geometry`` > ``line`` | ``arc``, ``lanes`` > ``laneOffset`` (cubic
polynomials in s), ``laneSection`` > ``left``/``center``/``right`` > ``lane`` > ``link``
(``predecessor``/``successor`` lane ids), ``width`` (cubic polynomials, several per lane), ``roadMark``
(type, color, width, weight, material, laneChange, height kept), ``speed`` (unit ``km/h``, ``m/s``
or ``mph``; ``m/s`` when the unit is absent; ``max="no limit"``/``"undefined"`` means +inf) and
``userData``. ``userData`` is allowed in ``OpenDRIVE``, ``header``, ``road``, ``laneSection`` and
``lane``; it is stored with its code, value, text and child elements.

evoscen extension (``userData`` codes starting with ``evoscen:``)
-----------------------------------------------------------------
``<userData code="evoscen:minSpeed" value="90 km/h"/>`` as a child of a ``<lane>`` gives the lane's
minimum speed for the whole lane section (value = number, a space, and a unit ``km/h``, ``m/s`` or
``mph``). It is converted to m/s in :attr:`Lane.min_speed_mps` (``None`` when absent). Any other
``evoscen:`` code, or ``evoscen:minSpeed`` elsewhere, is an error. Other vendors' codes are kept.

Everything else is rejected
---------------------------
Any element not listed above (``spiral``, ``poly3``, ``paramPoly3``, ``elevationProfile``,
``lateralProfile``, ``junction``, ``objects``, ``signals``, a lane ``border``, ``controller``, ...),
any attribute the OpenDRIVE 1.6 schema does not define for a supported element, and non-blank text
where the schema has none, raise :class:`~evoscen_sim.errors.InputError`. Malformed content also
raises it: not well-formed XML, a missing required attribute, a non-numeric or non-finite number,
an unknown enumeration value, geometry that is not contiguous (s, or x/y within
``GEOMETRY_TOLERANCE_M``), a road length that differs from the sum of geometry lengths, lane ids with
gaps or duplicates, lane sections whose ``s`` does not start at 0 and strictly increase or that lie
beyond the road length, ``sOffset`` values that do not strictly increase or lie beyond the section,
a first ``width`` whose ``sOffset`` is not 0, a width polynomial that becomes negative (below
``-WIDTH_TOLERANCE_M``) on the s range where it applies, a width on the center lane, more than one
road. Messages are one line: ``<file>:<line>: <element> ... <value> ... (expected ...)``.

Coordinates and units
---------------------
OpenDRIVE inertial x/y in metres, headings in radians (counter-clockwise from +x), ``s`` along the
reference line in metres, ``t``/``d`` lateral offset positive to the LEFT. Speeds are converted to
m/s; the raw value and unit are also kept.

Why one module of more than 600 lines
-------------------------------------
Every other module of evoscen_sim stays within 600 lines; this one does not, on purpose. It is the
supported subset of the OpenDRIVE schema written out element by element: the dataclasses of the
parsed map, then one parse function per element, all working on the private line-numbered element
tree (``_Node``) and checking context (``_Ctx``) that turn every violation into the one-line
``<file>:<line>:`` error. Split in two, either those private types would become an interface
between modules, or an element's dataclass would be read apart from the rules that fill it; kept
whole, what evoscen accepts from a map is read in one place, top to bottom.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Optional, Sequence
from xml.parsers import expat

from evoscen_sim.errors import InputError

#: Geometry pieces must join within this distance (m) in x/y, and in s.
GEOMETRY_TOLERANCE_M = 1e-3
#: A width polynomial may dip this far below 0 (m) through rounding (the model clamps it to 0).
WIDTH_TOLERANCE_M = 1e-9

SPEED_UNITS_TO_MPS: Mapping[str, float] = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}

LANE_TYPES = frozenset(
    "shoulder border driving stop none restricted parking median biking sidewalk curb exit entry "
    "onRamp offRamp connectingRamp bidirectional special1 special2 special3 roadWorks tram rail bus "
    "taxi HOV mwyEntry mwyExit".split()
)
ROAD_TYPES = frozenset(
    "unknown rural motorway town lowSpeed pedestrian bicycle townExpressway townCollector "
    "townArterial townPrivate townLocal townPlayStreet".split()
)
ROAD_MARK_TYPES = frozenset(
    ["none", "solid", "broken", "solid solid", "solid broken", "broken solid", "broken broken",
     "botts dots", "grass", "curb", "custom", "edge"]
)
ROAD_MARK_COLORS = frozenset("standard blue green red white yellow orange".split())
ROAD_MARK_WEIGHTS = frozenset(["standard", "bold"])
ROAD_MARK_LANE_CHANGE = frozenset(["increase", "decrease", "both", "none"])
BOOLEANS = {"true": True, "false": False, "1": True, "0": False}

EVOSCEN_MIN_SPEED_CODE = "evoscen:minSpeed"


# --------------------------------------------------------------------------------------------------
# Data model
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class XmlElement:
    """A raw XML element (used for the free-form content of ``userData``)."""

    tag: str
    attrs: Mapping[str, str]
    text: str
    children: tuple["XmlElement", ...]
    line: int


@dataclass(frozen=True)
class UserData:
    code: str
    value: Optional[str]
    text: str
    children: tuple[XmlElement, ...]
    line: int


@dataclass(frozen=True)
class Header:
    rev_major: int
    rev_minor: int
    name: Optional[str]
    version: Optional[str]
    date: Optional[str]
    vendor: Optional[str]
    geo_reference: Optional[str]
    attrs: Mapping[str, str]
    user_data: tuple[UserData, ...]
    line: int


@dataclass(frozen=True)
class RoadLinkTarget:
    """``<predecessor>``/``<successor>`` of a road (kept; evoscen follows no road links)."""

    element_type: str
    element_id: str
    contact_point: Optional[str]
    attrs: Mapping[str, str]
    line: int


@dataclass(frozen=True)
class Speed:
    """A speed limit; ``max_mps`` is +inf for ``no limit``/``undefined``."""

    max_mps: float
    max_raw: str
    unit: str
    line: int


@dataclass(frozen=True)
class RoadType:
    s_m: float
    type: str
    country: Optional[str]
    speed: Optional[Speed]
    line: int


@dataclass(frozen=True)
class Geometry:
    """One planView piece. ``kind`` is ``"line"`` (``curvature_per_m`` = 0) or ``"arc"``."""

    s_m: float
    x_m: float
    y_m: float
    hdg_rad: float
    length_m: float
    kind: str
    curvature_per_m: float
    line: int

    def end_pose(self) -> tuple[float, float, float]:
        """(x_m, y_m, hdg_rad) at the end of the piece (exact)."""
        k, h0, ln = self.curvature_per_m, self.hdg_rad, self.length_m
        half = 0.5 * k * ln
        chord = ln * (math.sin(half) / half if half != 0.0 else 1.0)
        return (
            self.x_m + chord * math.cos(h0 + half),
            self.y_m + chord * math.sin(h0 + half),
            h0 + k * ln,
        )


@dataclass(frozen=True)
class Poly3:
    """``value(ds) = a + b*ds + c*ds**2 + d*ds**3``; ``s_m`` is the (relative or absolute) start."""

    s_m: float
    a: float
    b: float
    c: float
    d: float
    line: int

    def value(self, ds: float) -> float:
        return self.a + ds * (self.b + ds * (self.c + ds * self.d))

    @property
    def is_constant(self) -> bool:
        return self.b == 0.0 and self.c == 0.0 and self.d == 0.0


@dataclass(frozen=True)
class RoadMark:
    s_offset_m: float
    type: str
    color: str
    width_m: Optional[float]
    weight: Optional[str]
    material: Optional[str]
    lane_change: Optional[str]
    height_m: Optional[float]
    line: int


@dataclass(frozen=True)
class LaneSpeed:
    s_offset_m: float
    max_mps: float
    max_raw: str
    unit: str
    line: int


@dataclass(frozen=True)
class Lane:
    """A lane of one lane section. ``widths`` have ``s_m`` relative to the section start."""

    id: int
    type: str
    level: bool
    predecessor_id: Optional[int]
    successor_id: Optional[int]
    widths: tuple[Poly3, ...]
    road_marks: tuple[RoadMark, ...]
    speeds: tuple[LaneSpeed, ...]
    min_speed_mps: Optional[float]
    user_data: tuple[UserData, ...]
    line: int


@dataclass(frozen=True)
class LaneSection:
    s_m: float
    end_s_m: float
    single_side: Optional[bool]
    left: tuple[Lane, ...]  # ids 1..n, ascending
    center: Lane  # id 0
    right: tuple[Lane, ...]  # ids -1..-n, i.e. from the reference line outwards
    user_data: tuple[UserData, ...]
    line: int


@dataclass(frozen=True)
class Road:
    id: str
    name: Optional[str]
    length_m: float
    junction: str
    rule: Optional[str]
    predecessor: Optional[RoadLinkTarget]
    successor: Optional[RoadLinkTarget]
    types: tuple[RoadType, ...]
    geometries: tuple[Geometry, ...]
    lane_offsets: tuple[Poly3, ...]  # s_m absolute
    lane_sections: tuple[LaneSection, ...]
    user_data: tuple[UserData, ...]
    line: int


@dataclass(frozen=True)
class OpenDriveMap:
    path: str
    header: Header
    road: Road
    user_data: tuple[UserData, ...] = field(default=())


# --------------------------------------------------------------------------------------------------
# XML reading (expat, with line numbers)
# --------------------------------------------------------------------------------------------------


class _Node:
    __slots__ = ("tag", "attrs", "line", "children", "text_parts")

    def __init__(self, tag: str, attrs: dict[str, str], line: int) -> None:
        self.tag = tag
        self.attrs = attrs
        self.line = line
        self.children: list[_Node] = []
        self.text_parts: list[str] = []

    @property
    def text(self) -> str:
        return "".join(self.text_parts)


def _read_xml(data: bytes, fname: str) -> _Node:
    parser = expat.ParserCreate()
    stack: list[_Node] = []
    root: list[_Node] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        node = _Node(tag, attrs, parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(tag: str) -> None:
        stack.pop()

    def chars(text: str) -> None:
        if stack:
            stack[-1].text_parts.append(text)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise InputError(
            f"{fname}:{exc.lineno}: not well-formed XML ({expat.errors.messages[exc.code]}, "
            f"column {exc.offset + 1}); expected an OpenDRIVE 1.6 document"
        ) from None
    except LookupError as exc:  # the XML declaration names an encoding Python does not know
        raise InputError(f"{fname}:1: the XML declaration names an unknown encoding ({exc}); "
                         "expected UTF-8 (or another encoding Python knows)") from None
    if not root:  # pragma: no cover - expat rejects documents without a root element
        raise InputError(f"{fname}:1: no XML root element; expected <OpenDRIVE>")
    return root[0]


# --------------------------------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------------------------------

_NUMBER_RE = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
_INT_RE = re.compile(r"^[+-]?\d+$")
_SPEED_VALUE_RE = re.compile(r"^\s*(\S+)\s*(km/h|m/s|mph)\s*$")


class _Ctx:
    def __init__(self, fname: str) -> None:
        self.fname = fname

    def error(self, node: _Node, message: str) -> InputError:
        return InputError(f"{self.fname}:{node.line}: {message}")

    # -- structure -------------------------------------------------------------------------------
    def attrs(self, node: _Node, required: Iterable[str], optional: Iterable[str] = ()) -> None:
        required = tuple(required)
        allowed = set(required) | set(optional)
        for name in node.attrs:
            if name not in allowed:
                raise self.error(
                    node,
                    f"<{node.tag}> attribute '{name}'='{node.attrs[name]}' is not supported "
                    f"(supported: {', '.join(sorted(allowed)) or 'none'})",
                )
        for name in required:
            if name not in node.attrs:
                raise self.error(
                    node, f"<{node.tag}> is missing the required attribute '{name}'"
                )

    def children(
        self, node: _Node, allowed: Mapping[str, tuple[int, Optional[int]]]
    ) -> dict[str, list[_Node]]:
        """Group children by tag; reject unknown tags and wrong counts (min, max or None)."""
        groups: dict[str, list[_Node]] = {tag: [] for tag in allowed}
        for child in node.children:
            if child.tag not in allowed:
                supported = ", ".join(allowed) if allowed else "no child elements"
                raise self.error(
                    child,
                    f"<{child.tag}> in <{node.tag}> is not supported (supported: {supported})",
                )
            groups[child.tag].append(child)
        for tag, (lo, hi) in allowed.items():
            n = len(groups[tag])
            if n < lo:
                raise self.error(
                    node, f"<{node.tag}> has {n} <{tag}> element(s) (expected at least {lo})"
                )
            if hi is not None and n > hi:
                extra = groups[tag][hi]
                raise self.error(
                    extra, f"<{node.tag}> has {n} <{tag}> elements (expected at most {hi})"
                )
        if node.text.strip():
            raise self.error(
                node, f"<{node.tag}> contains text {node.text.strip()[:40]!r} (expected none)"
            )
        return groups

    # -- values ----------------------------------------------------------------------------------
    def number(self, node: _Node, name: str, default: Optional[float] = None) -> float:
        raw = node.attrs.get(name)
        if raw is None:
            if default is not None:
                return default
            raise self.error(node, f"<{node.tag}> is missing the required attribute '{name}'")
        text = raw.strip()
        if not _NUMBER_RE.match(text):
            raise self.error(
                node,
                f"<{node.tag}> attribute '{name}'='{raw}' is not a number "
                "(expected a finite decimal number)",
            )
        value = float(text)
        if not math.isfinite(value):
            raise self.error(
                node, f"<{node.tag}> attribute '{name}'='{raw}' is not finite "
                "(expected a finite decimal number)"
            )
        return value

    def optional_number(self, node: _Node, name: str) -> Optional[float]:
        return self.number(node, name) if name in node.attrs else None

    def check(self, node: _Node, name: str, value: float, ok: bool, expected: str) -> None:
        if not ok:
            raise self.error(
                node, f"<{node.tag}> attribute '{name}'='{node.attrs.get(name, value)}' "
                f"is out of range (expected {expected})"
            )

    def integer(self, node: _Node, name: str) -> int:
        raw = node.attrs.get(name)
        if raw is None:
            raise self.error(node, f"<{node.tag}> is missing the required attribute '{name}'")
        if not _INT_RE.match(raw.strip()):
            raise self.error(
                node, f"<{node.tag}> attribute '{name}'='{raw}' is not an integer (expected an integer)"
            )
        return int(raw.strip())

    def enum(
        self, node: _Node, name: str, allowed: Iterable[str], required: bool = True
    ) -> Optional[str]:
        raw = node.attrs.get(name)
        if raw is None:
            if required:
                raise self.error(node, f"<{node.tag}> is missing the required attribute '{name}'")
            return None
        allowed = sorted(allowed)
        if raw not in allowed:
            raise self.error(
                node,
                f"<{node.tag}> attribute '{name}'='{raw}' is not allowed (expected one of: "
                f"{', '.join(allowed)})",
            )
        return raw

    def boolean(self, node: _Node, name: str, default: Optional[bool]) -> Optional[bool]:
        raw = node.attrs.get(name)
        if raw is None:
            return default
        if raw not in BOOLEANS:
            raise self.error(
                node, f"<{node.tag}> attribute '{name}'='{raw}' is not a boolean "
                "(expected true, false, 1 or 0)"
            )
        return BOOLEANS[raw]

    def increasing(
        self, nodes: Sequence[_Node], values: Sequence[float], name: str, what: str
    ) -> None:
        for prev, cur, node in zip(values, values[1:], nodes[1:]):
            if not cur > prev:
                raise self.error(
                    node,
                    f"<{node.tag}> attribute '{name}'='{node.attrs.get(name)}' does not increase "
                    f"(previous {what} is at {prev:g}; expected a value > {prev:g})",
                )


# --------------------------------------------------------------------------------------------------
# Element parsers
# --------------------------------------------------------------------------------------------------

_USER_DATA = {"userData": (0, None)}


def _xml_element(node: _Node) -> XmlElement:
    return XmlElement(
        node.tag, dict(node.attrs), node.text, tuple(_xml_element(c) for c in node.children), node.line
    )


def _user_data(ctx: _Ctx, nodes: Sequence[_Node], parent: str) -> tuple[UserData, ...]:
    out = []
    for node in nodes:
        ctx.attrs(node, ["code"], ["value"])
        code = node.attrs["code"]
        if code.startswith("evoscen:"):
            if code != EVOSCEN_MIN_SPEED_CODE:
                raise ctx.error(
                    node, f"<userData> code='{code}' is not a known evoscen code "
                    f"(supported: {EVOSCEN_MIN_SPEED_CODE})"
                )
            if parent != "lane":
                raise ctx.error(
                    node, f"<userData> code='{code}' in <{parent}> is not supported "
                    "(allowed only in <lane>)"
                )
            if node.children or node.text.strip():
                raise ctx.error(
                    node, f"<userData> code='{code}' has content (expected only a 'value' attribute)"
                )
        out.append(
            UserData(
                code,
                node.attrs.get("value"),
                node.text,
                tuple(_xml_element(c) for c in node.children),
                node.line,
            )
        )
    return tuple(out)


def _speed_value(ctx: _Ctx, node: _Node, unit_default: str = "m/s") -> tuple[float, str, str]:
    """(max_mps, max_raw, unit) of a <speed> element."""
    unit = ctx.enum(node, "unit", SPEED_UNITS_TO_MPS, required=False) or unit_default
    raw = node.attrs.get("max")
    if raw is None:
        raise ctx.error(node, f"<{node.tag}> is missing the required attribute 'max'")
    if raw.strip() in ("no limit", "undefined"):
        return math.inf, raw, unit
    value = ctx.number(node, "max")
    ctx.check(node, "max", value, value > 0.0, "a speed > 0, 'no limit' or 'undefined'")
    return value * SPEED_UNITS_TO_MPS[unit], raw, unit


def _parse_header(ctx: _Ctx, node: _Node) -> Header:
    ctx.attrs(
        node,
        ["revMajor", "revMinor"],
        ["name", "version", "date", "north", "south", "east", "west", "vendor"],
    )
    kids = ctx.children(node, {"geoReference": (0, 1), **_USER_DATA})
    major = ctx.integer(node, "revMajor")
    minor = ctx.integer(node, "revMinor")
    if major != 1:
        raise ctx.error(
            node, f"<header> attribute 'revMajor'='{node.attrs['revMajor']}' is not supported "
            "(expected 1)"
        )
    for name in ("north", "south", "east", "west"):
        if name in node.attrs:
            ctx.number(node, name)
    geo = None
    if kids["geoReference"]:
        g = kids["geoReference"][0]
        ctx.attrs(g, [])
        if g.children:
            raise ctx.error(
                g.children[0], f"<{g.children[0].tag}> in <geoReference> is not supported "
                "(supported: text only)"
            )
        geo = g.text.strip()
    return Header(
        rev_major=major,
        rev_minor=minor,
        name=node.attrs.get("name"),
        version=node.attrs.get("version"),
        date=node.attrs.get("date"),
        vendor=node.attrs.get("vendor"),
        geo_reference=geo,
        attrs=dict(node.attrs),
        user_data=_user_data(ctx, kids["userData"], "header"),
        line=node.line,
    )


def _parse_road_link(ctx: _Ctx, node: _Node) -> tuple[Optional[RoadLinkTarget], Optional[RoadLinkTarget]]:
    kids = ctx.children(node, {"predecessor": (0, 1), "successor": (0, 1)})
    ctx.attrs(node, [])
    out: list[Optional[RoadLinkTarget]] = []
    for tag in ("predecessor", "successor"):
        if not kids[tag]:
            out.append(None)
            continue
        n = kids[tag][0]
        ctx.attrs(n, ["elementType", "elementId"], ["contactPoint", "elementS", "elementDir"])
        ctx.children(n, {})
        ctx.enum(n, "elementType", ["road", "junction"])
        ctx.enum(n, "contactPoint", ["start", "end"], required=False)
        if "elementS" in n.attrs:
            ctx.number(n, "elementS")
        ctx.enum(n, "elementDir", ["+", "-"], required=False)
        out.append(
            RoadLinkTarget(
                n.attrs["elementType"], n.attrs["elementId"], n.attrs.get("contactPoint"),
                dict(n.attrs), n.line,
            )
        )
    return out[0], out[1]


def _parse_road_types(ctx: _Ctx, nodes: Sequence[_Node], length_m: float) -> tuple[RoadType, ...]:
    out = []
    for node in nodes:
        ctx.attrs(node, ["s", "type"], ["country"])
        kids = ctx.children(node, {"speed": (0, 1)})
        s = ctx.number(node, "s")
        ctx.check(node, "s", s, 0.0 <= s < length_m, f"0 <= s < road length {length_m:g}")
        rtype = ctx.enum(node, "type", ROAD_TYPES)
        speed = None
        if kids["speed"]:
            sp = kids["speed"][0]
            ctx.attrs(sp, ["max"], ["unit"])
            ctx.children(sp, {})
            mps, raw, unit = _speed_value(ctx, sp)
            speed = Speed(mps, raw, unit, sp.line)
        out.append(RoadType(s, str(rtype), node.attrs.get("country"), speed, node.line))
    ctx.increasing(nodes, [t.s_m for t in out], "s", "<type>")
    return tuple(out)


def _parse_plan_view(ctx: _Ctx, node: _Node, road: _Node, length_m: float) -> tuple[Geometry, ...]:
    ctx.attrs(node, [])
    kids = ctx.children(node, {"geometry": (1, None)})
    geoms: list[Geometry] = []
    for g in kids["geometry"]:
        ctx.attrs(g, ["s", "x", "y", "hdg", "length"])
        shape = ctx.children(g, {"line": (0, 1), "arc": (0, 1)})
        s = ctx.number(g, "s")
        x = ctx.number(g, "x")
        y = ctx.number(g, "y")
        hdg = ctx.number(g, "hdg")
        ln = ctx.number(g, "length")
        ctx.check(g, "length", ln, ln > 0.0, "a length > 0")
        if len(shape["line"]) + len(shape["arc"]) != 1:
            raise ctx.error(
                g, "<geometry> must contain exactly one of <line>, <arc> "
                f"(found {len(shape['line']) + len(shape['arc'])})"
            )
        if shape["line"]:
            ln_node = shape["line"][0]
            ctx.attrs(ln_node, [])
            ctx.children(ln_node, {})
            kind, k = "line", 0.0
        else:
            arc = shape["arc"][0]
            ctx.attrs(arc, ["curvature"])
            ctx.children(arc, {})
            kind, k = "arc", ctx.number(arc, "curvature")
            if abs(k) * ln >= 2.0 * math.pi:
                raise ctx.error(
                    arc, f"<arc> attribute 'curvature'='{arc.attrs['curvature']}' with length "
                    f"{ln:g} turns a full circle or more (expected |curvature|*length < 2*pi)"
                )
        geom = Geometry(s, x, y, hdg, ln, kind, k, g.line)
        if geoms:
            prev = geoms[-1]
            s_end = prev.s_m + prev.length_m
            if abs(s - s_end) > GEOMETRY_TOLERANCE_M:
                raise ctx.error(
                    g, f"<geometry> attribute 's'='{g.attrs['s']}' is not contiguous "
                    f"(previous geometry ends at s={s_end:.6f}; expected that value)"
                )
            xe, ye, _ = prev.end_pose()
            gap = math.hypot(x - xe, y - ye)
            if gap > GEOMETRY_TOLERANCE_M:
                raise ctx.error(
                    g, f"<geometry> start x='{g.attrs['x']}', y='{g.attrs['y']}' is not contiguous "
                    f"(previous geometry ends at x={xe:.6f}, y={ye:.6f}, gap {gap:.6g} m; expected "
                    f"a gap <= {GEOMETRY_TOLERANCE_M:g} m)"
                )
        elif abs(s) > GEOMETRY_TOLERANCE_M:
            raise ctx.error(g, f"<geometry> attribute 's'='{g.attrs['s']}' is not 0 (expected the "
                            "first geometry to start at s=0)")
        geoms.append(geom)
    total = geoms[-1].s_m + geoms[-1].length_m
    if abs(total - length_m) > GEOMETRY_TOLERANCE_M:
        raise ctx.error(
            road, f"<road> attribute 'length'='{road.attrs['length']}' does not match the planView "
            f"(geometries end at s={total:.6f}; expected that length within {GEOMETRY_TOLERANCE_M:g} m)"
        )
    return tuple(geoms)


def _parse_poly3_list(
    ctx: _Ctx, nodes: Sequence[_Node], s_name: str, lo: float, hi: float, what: str
) -> tuple[Poly3, ...]:
    out = []
    for node in nodes:
        ctx.attrs(node, [s_name, "a", "b", "c", "d"])
        ctx.children(node, {})
        s = ctx.number(node, s_name)
        ctx.check(node, s_name, s, lo <= s < hi, f"{lo:g} <= {s_name} < {hi:g} ({what})")
        out.append(
            Poly3(s, ctx.number(node, "a"), ctx.number(node, "b"), ctx.number(node, "c"),
                  ctx.number(node, "d"), node.line)
        )
    ctx.increasing(nodes, [p.s_m for p in out], s_name, f"<{nodes[0].tag if nodes else ''}>")
    return tuple(out)


def _cubic_min(p: Poly3, x0: float, x1: float) -> tuple[float, float]:
    """(min value, argmin) of polynomial ``p`` (in its local ds) on [x0, x1]."""
    cands = [x0, x1]
    # derivative b + 2c x + 3d x^2
    A, B, C = 3.0 * p.d, 2.0 * p.c, p.b
    if A != 0.0:
        disc = B * B - 4.0 * A * C
        if disc >= 0.0:
            r = math.sqrt(disc)
            cands += [(-B - r) / (2.0 * A), (-B + r) / (2.0 * A)]
    elif B != 0.0:
        cands.append(-C / B)
    vals = [(p.value(x), x) for x in cands if x0 <= x <= x1]
    return min(vals)


def _parse_lane(
    ctx: _Ctx, node: _Node, side: str, section_len_m: float
) -> Lane:
    ctx.attrs(node, ["id", "type"], ["level"])
    kids = ctx.children(
        node,
        {"link": (0, 1), "width": (0, None), "roadMark": (0, None), "speed": (0, None),
         **_USER_DATA},
    )
    lane_id = ctx.integer(node, "id")
    expected_sign = {"left": 1, "right": -1, "center": 0}[side]
    if (side == "center" and lane_id != 0) or (side != "center" and lane_id * expected_sign <= 0):
        want = {"left": "a positive id", "right": "a negative id", "center": "id 0"}[side]
        raise ctx.error(
            node, f"<lane> attribute 'id'='{node.attrs['id']}' in <{side}> is not allowed (expected {want})"
        )
    lane_type = str(ctx.enum(node, "type", LANE_TYPES))
    level = bool(ctx.boolean(node, "level", False))

    pred = succ = None
    if kids["link"]:
        link = kids["link"][0]
        ctx.attrs(link, [])
        lk = ctx.children(link, {"predecessor": (0, 1), "successor": (0, 1)})
        for tag in ("predecessor", "successor"):
            if lk[tag]:
                n = lk[tag][0]
                ctx.attrs(n, ["id"])
                ctx.children(n, {})
                if tag == "predecessor":
                    pred = ctx.integer(n, "id")
                else:
                    succ = ctx.integer(n, "id")

    span = f"inside the lane section of length {section_len_m:g}"
    if side == "center":
        if kids["width"]:
            w = kids["width"][0]
            raise ctx.error(w, "<width> in the center lane (id 0) is not allowed (expected no width)")
        widths: tuple[Poly3, ...] = ()
    else:
        if not kids["width"]:
            raise ctx.error(node, f"<lane> id={lane_id} has no <width> (expected at least one)")
        widths = _parse_poly3_list(ctx, kids["width"], "sOffset", 0.0, section_len_m, span)
        if widths[0].s_m != 0.0:
            w = kids["width"][0]
            raise ctx.error(
                w, f"<width> attribute 'sOffset'='{w.attrs['sOffset']}' of the first width is not 0 "
                "(expected 0: the width must be defined from the section start)"
            )
        for i, (p, wn) in enumerate(zip(widths, kids["width"])):
            x1 = (widths[i + 1].s_m if i + 1 < len(widths) else section_len_m) - p.s_m
            vmin, at = _cubic_min(p, 0.0, x1)
            if vmin < -WIDTH_TOLERANCE_M:
                raise ctx.error(
                    wn, f"<width> a={wn.attrs['a']} b={wn.attrs['b']} c={wn.attrs['c']} "
                    f"d={wn.attrs['d']} is negative ({vmin:.6g} m at ds={at:.6g}; expected a width "
                    ">= 0 over the whole range where it applies)"
                )

    marks = []
    for rm in kids["roadMark"]:
        ctx.attrs(rm, ["sOffset", "type", "color"],
                  ["weight", "material", "width", "laneChange", "height"])
        ctx.children(rm, {})
        s = ctx.number(rm, "sOffset")
        ctx.check(rm, "sOffset", s, 0.0 <= s < section_len_m, f"0 <= sOffset < {section_len_m:g} ({span})")
        width = ctx.optional_number(rm, "width")
        if width is not None:
            ctx.check(rm, "width", width, width >= 0.0, "a width >= 0")
        height = ctx.optional_number(rm, "height")
        marks.append(
            RoadMark(
                s_offset_m=s,
                type=str(ctx.enum(rm, "type", ROAD_MARK_TYPES)),
                color=str(ctx.enum(rm, "color", ROAD_MARK_COLORS)),
                width_m=width,
                weight=ctx.enum(rm, "weight", ROAD_MARK_WEIGHTS, required=False),
                material=rm.attrs.get("material"),
                lane_change=ctx.enum(rm, "laneChange", ROAD_MARK_LANE_CHANGE, required=False),
                height_m=height,
                line=rm.line,
            )
        )
    ctx.increasing(kids["roadMark"], [m.s_offset_m for m in marks], "sOffset", "<roadMark>")

    speeds = []
    for sp in kids["speed"]:
        if side == "center":
            raise ctx.error(sp, "<speed> in the center lane (id 0) is not allowed (expected none)")
        ctx.attrs(sp, ["sOffset", "max"], ["unit"])
        ctx.children(sp, {})
        s = ctx.number(sp, "sOffset")
        ctx.check(sp, "sOffset", s, 0.0 <= s < section_len_m, f"0 <= sOffset < {section_len_m:g} ({span})")
        mps, raw, unit = _speed_value(ctx, sp)
        speeds.append(LaneSpeed(s, mps, raw, unit, sp.line))
    ctx.increasing(kids["speed"], [v.s_offset_m for v in speeds], "sOffset", "<speed>")

    user_data = _user_data(ctx, kids["userData"], "lane")
    min_speed = None
    for ud, ud_node in zip(user_data, kids["userData"]):
        if ud.code != EVOSCEN_MIN_SPEED_CODE:
            continue
        if min_speed is not None:
            raise ctx.error(ud_node, f"<userData> code='{ud.code}' appears twice in one lane (expected once)")
        m = _SPEED_VALUE_RE.match(ud.value or "")
        if not m or not _NUMBER_RE.match(m.group(1)) or not math.isfinite(float(m.group(1))) \
                or float(m.group(1)) < 0.0:
            raise ctx.error(
                ud_node, f"<userData> code='{ud.code}' value='{ud.value}' is not a speed "
                "(expected a number >= 0, a space and a unit: km/h, m/s or mph, e.g. '90 km/h')"
            )
        min_speed = float(m.group(1)) * SPEED_UNITS_TO_MPS[m.group(2)]

    return Lane(
        id=lane_id, type=lane_type, level=level, predecessor_id=pred, successor_id=succ,
        widths=widths, road_marks=tuple(marks), speeds=tuple(speeds), min_speed_mps=min_speed,
        user_data=user_data, line=node.line,
    )


def _parse_side(ctx: _Ctx, node: _Node, side: str, section_len_m: float) -> tuple[Lane, ...]:
    ctx.attrs(node, [])
    kids = ctx.children(node, {"lane": (1, None)})
    lanes = [_parse_lane(ctx, n, side, section_len_m) for n in kids["lane"]]
    by_id: dict[int, Lane] = {}
    for lane, n in zip(lanes, kids["lane"]):
        if lane.id in by_id:
            raise ctx.error(n, f"<lane> attribute 'id'='{n.attrs['id']}' is duplicated in <{side}> "
                            "(expected unique ids)")
        by_id[lane.id] = lane
    if side == "center":
        return tuple(lanes)
    sign = 1 if side == "left" else -1
    expected = [sign * k for k in range(1, len(lanes) + 1)]
    if sorted(by_id, key=abs) != expected:
        missing = sorted(set(expected) - set(by_id), key=abs)
        raise ctx.error(
            node, f"<{side}> lane ids {sorted(by_id, key=abs)} have a gap (missing {missing}; "
            f"expected ids {expected[0]}..{expected[-1]} without gaps)"
        )
    return tuple(by_id[i] for i in expected)


def _parse_lanes(ctx: _Ctx, node: _Node, length_m: float) -> tuple[tuple[Poly3, ...], tuple[LaneSection, ...]]:
    ctx.attrs(node, [])
    kids = ctx.children(node, {"laneOffset": (0, None), "laneSection": (1, None)})
    offsets = _parse_poly3_list(ctx, kids["laneOffset"], "s", 0.0, length_m, "on the road")

    sec_nodes = kids["laneSection"]
    starts = []
    for n in sec_nodes:
        ctx.attrs(n, ["s"], ["singleSide"])
        s = ctx.number(n, "s")
        ctx.check(n, "s", s, 0.0 <= s < length_m, f"0 <= s < road length {length_m:g}")
        starts.append(s)
    if starts[0] != 0.0:
        n = sec_nodes[0]
        raise ctx.error(n, f"<laneSection> attribute 's'='{n.attrs['s']}' of the first section is "
                        "not 0 (expected 0)")
    ctx.increasing(sec_nodes, starts, "s", "<laneSection>")

    sections = []
    for i, n in enumerate(sec_nodes):
        end = starts[i + 1] if i + 1 < len(starts) else length_m
        sk = ctx.children(n, {"left": (0, 1), "center": (1, 1), "right": (0, 1), **_USER_DATA})
        left = _parse_side(ctx, sk["left"][0], "left", end - starts[i]) if sk["left"] else ()
        center = _parse_side(ctx, sk["center"][0], "center", end - starts[i])
        if len(center) != 1:
            raise ctx.error(sk["center"][0], f"<center> has {len(center)} lanes (expected exactly one, id 0)")
        right = _parse_side(ctx, sk["right"][0], "right", end - starts[i]) if sk["right"] else ()
        sections.append(
            LaneSection(
                s_m=starts[i], end_s_m=end, single_side=ctx.boolean(n, "singleSide", None),
                left=left, center=center[0], right=right,
                user_data=_user_data(ctx, sk["userData"], "laneSection"), line=n.line,
            )
        )
    return offsets, tuple(sections)


def _parse_road(ctx: _Ctx, node: _Node) -> Road:
    ctx.attrs(node, ["length", "id", "junction"], ["name", "rule"])
    kids = ctx.children(
        node,
        {"link": (0, 1), "type": (0, None), "planView": (1, 1), "lanes": (1, 1), **_USER_DATA},
    )
    length = ctx.number(node, "length")
    ctx.check(node, "length", length, length > 0.0, "a length > 0")
    if node.attrs["junction"].strip() != "-1":
        raise ctx.error(
            node, f"<road> attribute 'junction'='{node.attrs['junction']}' is not supported "
            "(expected -1: junctions are not supported)"
        )
    rule = ctx.enum(node, "rule", ["RHT", "LHT"], required=False)
    pred = succ = None
    if kids["link"]:
        pred, succ = _parse_road_link(ctx, kids["link"][0])
    types = _parse_road_types(ctx, kids["type"], length)
    geoms = _parse_plan_view(ctx, kids["planView"][0], node, length)
    offsets, sections = _parse_lanes(ctx, kids["lanes"][0], length)
    return Road(
        id=node.attrs["id"], name=node.attrs.get("name"), length_m=length,
        junction=node.attrs["junction"], rule=rule, predecessor=pred, successor=succ,
        types=types, geometries=geoms, lane_offsets=offsets, lane_sections=sections,
        user_data=_user_data(ctx, kids["userData"], "road"), line=node.line,
    )


# --------------------------------------------------------------------------------------------------
# Public entry points
# --------------------------------------------------------------------------------------------------


def parse_opendrive_bytes(data: bytes, fname: str = "<string>") -> OpenDriveMap:
    """Parse OpenDRIVE content; ``fname`` is used in error messages only."""
    ctx = _Ctx(fname)
    root = _read_xml(data, fname)
    if root.tag != "OpenDRIVE":
        raise ctx.error(root, f"root element <{root.tag}> is not supported (expected <OpenDRIVE>)")
    ctx.attrs(root, [], ["xmlns", "xmlns:xsi", "xsi:noNamespaceSchemaLocation", "xsi:schemaLocation"])
    kids = ctx.children(root, {"header": (1, 1), "road": (1, None), **_USER_DATA})
    if len(kids["road"]) > 1:
        extra = kids["road"][1]
        raise ctx.error(
            extra, f"<road> id='{extra.attrs.get('id', '?')}' is a second road; "
            f"found {len(kids['road'])} roads (expected exactly one: evoscen simulates a single road)"
        )
    header = _parse_header(ctx, kids["header"][0])
    road = _parse_road(ctx, kids["road"][0])
    return OpenDriveMap(
        path=fname, header=header, road=road,
        user_data=_user_data(ctx, kids["userData"], "OpenDRIVE"),
    )


def parse_opendrive(path: "str | os.PathLike[str]") -> OpenDriveMap:
    """Read and validate an ``.xodr`` file. Raises :class:`InputError` on any problem."""
    fname = os.fspath(path)
    from evoscen_sim.limits import MAX_MAP_BYTES, read_bytes_limited

    data = read_bytes_limited(fname, fname, "OpenDRIVE file", MAX_MAP_BYTES)
    return parse_opendrive_bytes(data, fname)


__all__ = [
    "GEOMETRY_TOLERANCE_M", "WIDTH_TOLERANCE_M", "SPEED_UNITS_TO_MPS", "EVOSCEN_MIN_SPEED_CODE",
    "XmlElement", "UserData", "Header", "RoadLinkTarget", "Speed", "RoadType", "Geometry", "Poly3",
    "RoadMark", "LaneSpeed", "Lane", "LaneSection", "Road", "OpenDriveMap",
    "parse_opendrive", "parse_opendrive_bytes",
]
