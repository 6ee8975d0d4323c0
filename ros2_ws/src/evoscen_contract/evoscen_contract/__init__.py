"""evoscen_contract: the topic contract and table <-> numpy conversions. The ground of every package: it
imports nothing of evoscen.

Submodules:

* :mod:`evoscen_contract.contract` - the contract's facts without ROS: topic and type
  names, node names, table columns, role and policy codes, event names and keys, exit
  statuses (what the cores import);
* :mod:`evoscen_contract.topics` - the ROS binding: message classes, QoS, publishers,
  event encoding, message builders (``CONTRACT``, ``TOPICS``); re-exports the facts;
* :mod:`evoscen_contract.tables` - flat typed tables (PointCloud2 <-> numpy) and
  time stamps;
* :mod:`evoscen_contract.cdr` - canonical CDR encoders and the table decoder (ROS-free);
* :mod:`evoscen_contract.qos` - ROS-free QoS descriptions (-> rclpy / rosbag2).

Import the submodules directly (``from evoscen_contract.topics import WORLD``); this
package ``__init__`` imports nothing so that ``evoscen_contract.contract``,
``evoscen_contract.cdr`` and ``evoscen_contract.qos`` stay usable without ROS message
packages.
"""
