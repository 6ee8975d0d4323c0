"""OpenDRIVE parser: the shipped map, and one-line InputErrors for broken files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from evoscen_sim.errors import InputError
from evoscen_sim.road.opendrive import parse_opendrive
from evoscen_sim.road.road_model import DEFAULT_MAP_PATH, load_road

# A small valid map: 100 m line + 50 m arc, two 3.5 m lanes, one lane section.
MINIMAL = """<?xml version="1.0"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="6" name="mini"/>
  <road name="r" length="150" id="1" junction="-1">
    <planView>
      <geometry s="0" x="0" y="0" hdg="0" length="100">
        <line/>
      </geometry>
      <geometry s="100" x="100" y="0" hdg="0" length="50">
        <arc curvature="0.01"/>
      </geometry>
    </planView>
    <lanes>
      <laneSection s="0">
        <center>
          <lane id="0" type="none"/>
        </center>
        <right>
          <lane id="-1" type="driving">
            <width sOffset="0" a="3.5" b="0" c="0" d="0"/>
            <speed sOffset="0" max="100" unit="km/h"/>
          </lane>
          <lane id="-2" type="driving">
            <width sOffset="0" a="3.5" b="0" c="0" d="0"/>
          </lane>
        </right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"""


def write(tmp_path: Path, text: str, name: str = "broken.xodr") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def line_of(text: str, needle: str) -> int:
    for i, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return i
    raise AssertionError(needle)


def expect_error(tmp_path: Path, text: str, line: int, *fragments: str) -> str:
    path = write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        parse_opendrive(path)
    msg = str(exc.value)
    assert "\n" not in msg
    assert "broken.xodr" in msg
    assert f"broken.xodr:{line}:" in msg, msg
    for frag in fragments:
        assert frag in msg, (frag, msg)
    return msg


# ------------------------------------------------------------------------------------ valid input


def test_shipped_map_parses() -> None:
    odr = parse_opendrive(DEFAULT_MAP_PATH)
    road = odr.road
    assert odr.header.name == "evoscen_onramp" and (odr.header.rev_major, odr.header.rev_minor) == (1, 6)
    assert road.length_m == 2393.76
    assert [g.kind for g in road.geometries] == ["line", "arc", "line"]
    assert [g.s_m for g in road.geometries] == [0.0, 1000.0, 1600.0]
    assert road.geometries[1].curvature_per_m == 0.0005
    assert [s.s_m for s in road.lane_sections] == [0.0, 600.0, 900.0, 960.0]
    assert [len(s.right) for s in road.lane_sections] == [4, 5, 5, 4]
    taper = road.lane_sections[2].right[4].widths[0]
    assert (taper.a, taper.b) == (3.5, 0.0)
    assert taper.c == pytest.approx(-3 * 3.5 / 60**2, rel=1e-15)
    assert taper.d == pytest.approx(2 * 3.5 / 60**3, rel=1e-15)
    lane = road.lane_sections[0].right[0]
    assert lane.type == "driving" and lane.speeds[0].unit == "km/h"
    assert lane.speeds[0].max_mps == pytest.approx(120 / 3.6)
    assert lane.min_speed_mps == pytest.approx(25.0)
    assert road.lane_sections[1].right[4].min_speed_mps is None
    assert lane.road_marks[0].type == "broken" and lane.road_marks[0].color == "white"
    assert road.lane_sections[0].center.road_marks[0].type == "solid"
    assert road.lane_sections[1].right[4].successor_id == -5
    # the arc end matches the next geometry's start (contiguity is checked by the parser)
    x, y, h = road.geometries[1].end_pose()
    assert (x, y, h) == pytest.approx((1000 + 2000 * math.sin(0.3), 2000 * (1 - math.cos(0.3)), 0.3))


def test_minimal_map_and_speed_units(tmp_path: Path) -> None:
    text = MINIMAL.replace('max="100" unit="km/h"', 'max="50" unit="mph"')
    road = load_road(write(tmp_path, text, "ok.xodr"))
    assert road.num_lanes == 2 and road.length_m == 150.0
    assert road.speed_limit_max_mps(1, 10.0) == pytest.approx(50 * 0.44704)
    assert np.isinf(road.speed_limit_max_mps(0, 10.0))  # no <speed>, no road type speed
    assert road.speed_limit_min_mps(1, 10.0) == 0.0
    text = MINIMAL.replace('max="100" unit="km/h"', 'max="30"')  # no unit -> m/s
    assert load_road(write(tmp_path, text, "ok2.xodr")).speed_limit_max_mps(1, 10.0) == 30.0


def test_road_type_speed_is_the_fallback(tmp_path: Path) -> None:
    text = MINIMAL.replace(
        "    <planView>", '    <type s="0" type="motorway"><speed max="80" unit="km/h"/></type>\n    <planView>'
    )
    road = load_road(write(tmp_path, text, "ok.xodr"))
    assert road.speed_limit_max_mps(0, 10.0) == pytest.approx(80 / 3.6)
    assert road.speed_limit_max_mps(1, 10.0) == pytest.approx(100 / 3.6)


def test_lane_offset_and_several_widths(tmp_path: Path) -> None:
    text = MINIMAL.replace("    <lanes>\n", '    <lanes>\n      <laneOffset s="0" a="1.0" b="0" c="0" d="0"/>\n')
    text = text.replace(
        '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>\n          </lane>',
        '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>\n'
        '            <width sOffset="50" a="3.5" b="0.01" c="0" d="0"/>\n          </lane>',
    )
    road = load_road(write(tmp_path, text, "ok.xodr"))
    assert road.road_edges_d(10.0)[1] == pytest.approx(1.0)
    assert road.lane_center_d(1, 10.0) == pytest.approx(1.0 - 1.75)
    assert road.lane_width(0, 70.0) == pytest.approx(3.5 + 0.01 * 20)
    assert road.lane_center_d(0, 70.0) == pytest.approx(1.0 - 3.5 - (3.7 / 2))


# ------------------------------------------------------------------------------------ errors


def test_not_xml(tmp_path: Path) -> None:
    text = "<OpenDRIVE>\n  <header revMajor='1' revMinor='6'>\n</OpenDRIVE>\n"
    expect_error(tmp_path, text, 3, "not well-formed XML")


def test_unknown_encoding_in_the_xml_declaration(tmp_path: Path) -> None:
    # found by scripts/fault_campaign.py: a mangled declaration raised LookupError from the parser
    text = MINIMAL.replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="UTF-8e-09"?>')
    expect_error(tmp_path, text, 1, "unknown encoding", "UTF-8e-09")


def test_spiral_geometry(tmp_path: Path) -> None:
    text = MINIMAL.replace('<arc curvature="0.01"/>', '<spiral curvStart="0" curvEnd="0.01"/>')
    msg = expect_error(tmp_path, text, line_of(text, "<spiral"), "<spiral>", "<geometry>", "not supported")
    assert "line, arc" in msg


def test_non_numeric_width(tmp_path: Path) -> None:
    text = MINIMAL.replace('<width sOffset="0" a="3.5"', '<width sOffset="0" a="wide"', 1)
    expect_error(tmp_path, text, line_of(text, 'a="wide"'), "<width>", "'a'", "wide", "not a number")


def test_missing_road_length(tmp_path: Path) -> None:
    text = MINIMAL.replace(' length="150"', "")
    expect_error(tmp_path, text, line_of(text, "<road "), "<road>", "'length'", "missing")


def test_unknown_element(tmp_path: Path) -> None:
    text = MINIMAL.replace("    <lanes>\n", "    <lanes>\n      <frobnicate/>\n")
    expect_error(tmp_path, text, line_of(text, "<frobnicate"), "<frobnicate>", "<lanes>", "not supported")


@pytest.mark.parametrize(
    "element",
    ['<elevationProfile/>', '<lateralProfile/>', '<objects/>', '<signals/>'],
)
def test_unsupported_road_children(tmp_path: Path, element: str) -> None:
    text = MINIMAL.replace("    <lanes>\n", f"    {element}\n    <lanes>\n")
    tag = element.strip("</>")
    expect_error(tmp_path, text, line_of(text, element), f"<{tag}>", "<road>", "not supported")


def test_junction_and_second_road(tmp_path: Path) -> None:
    text = MINIMAL.replace("</OpenDRIVE>", '<junction id="5" name="j"/>\n</OpenDRIVE>')
    expect_error(tmp_path, text, line_of(text, "<junction"), "<junction>", "<OpenDRIVE>", "not supported")
    road = MINIMAL[MINIMAL.index("  <road"):MINIMAL.index("</OpenDRIVE>")]
    text = MINIMAL.replace("</OpenDRIVE>", road.replace('id="1"', 'id="2"') + "</OpenDRIVE>")
    lines = [i for i, ln in enumerate(text.splitlines(), 1) if "<road " in ln]
    expect_error(tmp_path, text, lines[1], "<road>", "second road", "exactly one")


def test_lane_border(tmp_path: Path) -> None:
    text = MINIMAL.replace('<width sOffset="0" a="3.5" b="0" c="0" d="0"/>\n          </lane>',
                           '<border sOffset="0" a="3.5" b="0" c="0" d="0"/>\n          </lane>')
    expect_error(tmp_path, text, line_of(text, "<border"), "<border>", "<lane>", "not supported")


def test_geometry_gap(tmp_path: Path) -> None:
    text = MINIMAL.replace('<geometry s="100" x="100"', '<geometry s="100" x="101"')
    expect_error(tmp_path, text, line_of(text, 'x="101"'), "<geometry>", "not contiguous", "101")
    text = MINIMAL.replace('<geometry s="100" x="100"', '<geometry s="101" x="100"').replace(
        'length="150"', 'length="151"')
    expect_error(tmp_path, text, line_of(text, 's="101"'), "<geometry>", "'s'='101'", "not contiguous")


def test_road_length_mismatch(tmp_path: Path) -> None:
    text = MINIMAL.replace('length="150"', 'length="160"')
    expect_error(tmp_path, text, line_of(text, "<road "), "<road>", "'length'='160'", "150")


def test_lane_id_gap(tmp_path: Path) -> None:
    text = MINIMAL.replace('<lane id="-2"', '<lane id="-3"')
    expect_error(tmp_path, text, line_of(text, "<right>"), "<right>", "gap", "-2")


def test_sections_not_increasing_and_beyond_length(tmp_path: Path) -> None:
    sec = MINIMAL[MINIMAL.index("      <laneSection"):MINIMAL.index("    </lanes>")]
    text = MINIMAL.replace("    </lanes>", sec.replace('s="0"', 's="80"') + sec + "    </lanes>")
    lines = [i for i, ln in enumerate(text.splitlines(), 1) if "<laneSection" in ln]
    expect_error(tmp_path, text, lines[2], "<laneSection>", "'s'='0'", "does not increase")
    text = MINIMAL.replace("    </lanes>", sec.replace('s="0"', 's="150"') + "    </lanes>")
    lines = [i for i, ln in enumerate(text.splitlines(), 1) if "<laneSection" in ln]
    expect_error(tmp_path, text, lines[1], "<laneSection>", "'s'='150'", "road length 150")


def test_negative_width(tmp_path: Path) -> None:
    text = MINIMAL.replace('<width sOffset="0" a="3.5" b="0" c="0" d="0"/>',
                           '<width sOffset="0" a="3.5" b="-0.05" c="0" d="0"/>', 1)
    expect_error(tmp_path, text, line_of(text, 'b="-0.05"'), "<width>", "negative", ">= 0")


def test_bad_enums_and_units(tmp_path: Path) -> None:
    text = MINIMAL.replace('unit="km/h"', 'unit="knots"')
    expect_error(tmp_path, text, line_of(text, "knots"), "<speed>", "'unit'='knots'", "km/h", "mph")
    text = MINIMAL.replace('<lane id="-2" type="driving"', '<lane id="-2" type="highway"')
    expect_error(tmp_path, text, line_of(text, "highway"), "<lane>", "'type'='highway'", "driving")


def test_unknown_attribute(tmp_path: Path) -> None:
    text = MINIMAL.replace('<line/>', '<line foo="1"/>')
    expect_error(tmp_path, text, line_of(text, 'foo="1"'), "<line>", "'foo'", "not supported")


def test_evoscen_user_data(tmp_path: Path) -> None:
    ud = '<userData code="evoscen:minSpeed" value="60 km/h"/>\n'
    text = MINIMAL.replace('<lane id="-2" type="driving">\n', '<lane id="-2" type="driving">\n' + ud)
    road = load_road(write(tmp_path, text, "ok.xodr"))
    assert road.speed_limit_min_mps(0, 10.0) == pytest.approx(60 / 3.6)
    bad = text.replace('value="60 km/h"', 'value="fast"')
    expect_error(tmp_path, bad, line_of(bad, "fast"), "<userData>", "evoscen:minSpeed", "km/h")
    bad = text.replace("evoscen:minSpeed", "evoscen:maxSped")
    expect_error(tmp_path, bad, line_of(bad, "maxSped"), "<userData>", "evoscen:maxSped", "not a known")


def test_model_level_rejections(tmp_path: Path) -> None:
    text = MINIMAL.replace('<lane id="-2" type="driving"', '<lane id="-2" type="sidewalk"')
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=r"broken\.xodr:\d+: <lane> id=-2 .*'sidewalk'"):
        load_road(path)
    left = ('        <left>\n          <lane id="1" type="driving">\n'
            '            <width sOffset="0" a="3.5" b="0" c="0" d="0"/>\n          </lane>\n        </left>\n')
    text = MINIMAL.replace("        <center>\n", left + "        <center>\n")
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=r"broken\.xodr:\d+: <lane> id=1 in <left> is not supported"):
        load_road(path)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="nothere.xodr"):
        parse_opendrive(tmp_path / "nothere.xodr")


def test_error_is_value_error() -> None:
    assert issubclass(InputError, ValueError)


def test_road_facts_mainline_and_merge_lane(tmp_path: Path) -> None:
    """The mainline lanes are those from the road's start, rightmost first; lane I (index 0) is the merge
    lane when it starts later (the shipped map: at s = 600 m), else a mainline lane and no merge lane."""
    from evoscen_sim.road.road_model import MERGE_LANE

    shipped = load_road(DEFAULT_MAP_PATH)
    assert MERGE_LANE == 0 and shipped.merge_lane == 0
    assert shipped.mainline_lanes == (1, 2, 3, 4) and shipped.has_merge_lane
    two = load_road(write(tmp_path, MINIMAL, "two.xodr"))  # both lanes from s = 0: no merge lane
    assert two.mainline_lanes == (0, 1) and not two.has_merge_lane
