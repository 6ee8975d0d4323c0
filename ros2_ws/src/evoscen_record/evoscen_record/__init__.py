"""evoscen_record: the run's rosbag2 (MCAP storage) bag, written, read and reindexed. May import the
simulation and the contract (the evaluation and the runners import it, never the reverse).

Submodules:

* :mod:`evoscen_record.recorder` - :class:`~evoscen_record.recorder.BagRecorder` (write a
  rosbag2 MCAP bag from serialized CDR), on :mod:`evoscen_record.bag_file` (the file and its
  safe points), :mod:`evoscen_record.mcap_internals` (the fast write paths) and
  :mod:`evoscen_record.metadata_yaml` (``metadata.yaml``);
* :mod:`evoscen_record.ordered_bag` - :class:`~evoscen_record.ordered_bag.OrderedBag`, the
  canonical message order;
* :mod:`evoscen_record.canonical_cdr` - CDR re-serialized with zeroed padding;
* :mod:`evoscen_record.schemas` - rosbag2-style concatenated ``ros2msg`` definitions;
* :mod:`evoscen_record.scenario_record` - the scenario's MCAP metadata record;
* :mod:`evoscen_record.bag_reader` - :func:`~evoscen_record.bag_reader.open_bag_reader`;
* :mod:`evoscen_record.reindex` - a bag finished from its complete chunks;
* :mod:`evoscen_record.step_recorder` and :mod:`evoscen_record.bag_writer` - the in-process
  runner's recorder, inline or in a forked writer process.

Import the submodules directly; this ``__init__`` imports nothing.
"""
