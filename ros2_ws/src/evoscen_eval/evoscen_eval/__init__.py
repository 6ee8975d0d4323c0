"""evoscen_eval: recording (rosbag2/MCAP), metrics and evaluation.

Submodules:

* :mod:`evoscen_eval.recorder` - :class:`~evoscen_eval.recorder.BagRecorder` (write a
  rosbag2 MCAP bag from serialized CDR) and
  :func:`~evoscen_eval.bag_reader.open_bag_reader`;
* :mod:`evoscen_eval.schemas` - rosbag2-style concatenated ``ros2msg`` definitions.

Import the submodules directly; this ``__init__`` imports nothing.
"""
