"""evoscen's experiments: many runs and what they say (docs/architecture.md §1).

Holds campaigns on Ray (``campaign``, ``campaign_spec``, ``campaign_summary``, ``ray_leftovers``,
``campaign_driver``), the method's experiments and their rounds (``experiments``, ``intelligence_experiment``,
``complexity_experiment``, ``traffic_experiment``, ``fidelity_experiment``, ``exposures_by_rule``,
``traffic_runs``), sensitivity and replication (``sensitivity``, ``sensitivity_experiment``,
``sensitivity_tables``, ``sensitivity_sequential``, ``replication``, ``sequential``), the planner leaderboard (``leaderboard``),
statistics (``stats``), benchmarks (``bench``, ``bench_graph``, ``bench_fidelity``, ``bench_run_costs``,
``profiling``, ``sumo_baseline``), the fault campaign (``faults``, ``fault_runs``, ``host_faults``,
``input_fuzz``) and the README's results table (``results_table``): the work of the scripts' doors
(``scripts/``). May import every package below it — the runners (:mod:`evoscen_bringup`), the
evaluation, the recording, the drivers, the simulation and the contract — and nothing above it (the
face, :mod:`evoscen`).
"""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the paths these modules had in evoscen_bringup keep working until 0.8.0, with a warning
