"""evoscen_contract: the topic contract and table <-> numpy conversions.

Submodules:

* :mod:`evoscen_contract.topics` - topic names, types, QoS, publishers, table columns,
  policy codes, event encoding, message builders (``CONTRACT``, ``TOPICS``);
* :mod:`evoscen_contract.tables` - flat typed tables (PointCloud2 <-> numpy) and
  time stamps;
* :mod:`evoscen_contract.qos` - ROS-free QoS descriptions (-> rclpy / rosbag2).

Import the submodules directly (``from evoscen_contract.topics import WORLD``); this
package ``__init__`` imports nothing so that ``evoscen_contract.qos`` stays usable
without ROS message packages.
"""
