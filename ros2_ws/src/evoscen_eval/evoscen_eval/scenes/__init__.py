"""Scenes room of evoscen_eval: a run shown and exchanged — OpenSCENARIO and CommonRoad export and its
read-back (``scenario_export``, ``xosc_readback``, ``export_vehicles``: the vehicles' limits and names;
``exports``: ranges and clips exported and checked; ``event_ranges``: a range around an event, off shifts),
critical-event clips (``clips``), the replay of a bag on the wire (``replay``, its rclpy side
``replay_wire``). May import the scoring room, the recording, the simulation and the contract."""
