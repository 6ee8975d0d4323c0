"""evoscen's experiments: many runs and what they say (docs/architecture.md §1).

Holds campaigns on Ray (``campaign``, ``campaign_spec``, ``campaign_summary``, ``ray_leftovers``), the
method's experiments and their rounds (``experiments``), sensitivity and replication (``sensitivity``,
``replication``), statistics (``stats``), the README's results table (``results_table``) and the fault
campaign (``faults``, ``fault_runs``, ``host_faults``, ``input_fuzz``). May import
every package below it — the runners (:mod:`evoscen_bringup`), the evaluation, the recording, the
drivers, the simulation and the contract — and nothing above it (the face, :mod:`evoscen`).
"""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the paths these modules had in evoscen_bringup keep working until 0.8.0, with a warning
