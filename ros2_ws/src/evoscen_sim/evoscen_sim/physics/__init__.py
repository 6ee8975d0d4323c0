"""Physics, free of ROS: the vehicles' bodies and motion (``vehicle``, ``control``, ``idm``), contact
(``collision``), who is next to whom (``neighbors``), the world's state and fixed step (``world``) and
the traffic window its step runs (``window``). May import the ground floor, the configuration, the road
and the contract; no other room (docs/architecture.md §1)."""
