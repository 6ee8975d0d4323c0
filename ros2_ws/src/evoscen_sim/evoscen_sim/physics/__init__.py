"""Physics, free of ROS: the vehicles' bodies and motion (``vehicle``, ``control``, ``idm``), contact
(``collision``), who is next to whom (``neighbors``) and the world's state and fixed step (``world``)."""
