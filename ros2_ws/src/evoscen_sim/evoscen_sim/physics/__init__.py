"""The simulation core, free of ROS: the world step and its parts, traffic, spawn, step loop, dangerous states, events, the drivers' view."""
