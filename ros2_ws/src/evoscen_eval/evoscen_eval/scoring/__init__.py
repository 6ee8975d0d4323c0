"""Scoring room of evoscen_eval: a run read into arrays (``rundata``), scored as it streams
(``streaming``, ``metrics``, ``sut_collisions``, ``sut_lane_changes``, ``exposure_rules``), and reported
(``report``, ``report_text``: report.md's and the printed score lines' words, ``plot_inputs``,
``animation``: the report's pictures; ``bag_report``: a bag scored and reported offline); ``run_fixtures``
for tests.
May import the recording, the simulation and the contract; nothing else of evoscen_eval."""
