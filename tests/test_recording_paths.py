"""A recorded in-process run gives the same bag through the recorder's new and earlier paths (issue 14).

The run (300 steps of the default scenario: world, commands, clock, odometry, events with and
without statuses, vehicle markers every 5th step, roster and map markers once) is recorded
three times: as shipped (each step's messages handed to ``BagRecorder.write_parts`` in canonical
order, ``mcap_internals.ChunkMessages``, the compiled marker kernel, events encoded directly); with the earlier
write path (every message through ``OrderedBag``, ``mcap_internals.FastMessages``, markers marker by marker in Python,
events and map markers serialized by rclpy and canonicalized by the recorder); and through the
mcap library's own ``add_message``; and as shipped with the bag written by a forked writer
process (``bag_writer="process"``, evoscen_record.bag_writer; the others inline). The four
``.mcap`` files must be equal byte for byte.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_recorded_run_is_the_same_through_every_path(tmp_path: Path, monkeypatch) -> None:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_contract import messages as M
    from evoscen_contract import topics as T
    from evoscen_contract.cdr_markers import VehicleMarkersEncoder
    from evoscen_contract.markers import road_markers
    from evoscen_record import mcap_internals as MI
    from evoscen_record import recorder as R
    from evoscen_record.step_recorder import StepRecorder
    from evoscen_sim.config.scenario_config import load_scenario_config
    from rclpy.serialization import serialize_message

    cfg = load_scenario_config(None, {"steps": 300})

    def record(name: str, writer: str = "inline") -> bytes:
        run_inprocess(cfg, bag_dir=tmp_path / name / "bag", bag_writer=writer)
        return (tmp_path / name / "bag" / "bag_0.mcap").read_bytes()

    new = record("new")
    process = record("process", "process")
    with monkeypatch.context() as m:
        m.setattr(StepRecorder, "direct", False)  # every message through OrderedBag
        m.setattr(MI.ChunkMessages, "usable", staticmethod(lambda writer: False))
        m.setattr(VehicleMarkersEncoder, "encode", VehicleMarkersEncoder.encode_python)
        # events and map markers as rclpy's bytes: the recorder canonicalizes them
        m.setattr(M.WorldMessages, "events", lambda self, events, t_ns: self._no_events.encode(t_ns) if not events
                  else serialize_message(T.events_message(events, t_ns)))
        m.setattr(M, "encode_road_markers", lambda road, t_ns: serialize_message(road_markers(road, t_ns)))
        rclpy_topics = (T.EVENTS.name, T.MAP_MARKERS.name)
        m.setattr(R.BagRecorder, "write_many",
                  lambda self, msgs: [self.write(topic, data, t, canonical=canonical and topic not in rclpy_topics)
                                      for t, topic, data, canonical in msgs] and None)
        old = record("old")
        m.setattr(MI.FastMessages, "usable", staticmethod(lambda writer: False))
        library = record("library")
    assert old == library
    assert new == old
    assert process == new
