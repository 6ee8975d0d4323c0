"""The background traffic: where it starts (``spawn``), what it is made of (``makeup``) and the traffic
section's parameters checked against the road (``scenario_params``); the traffic window that moves with
the SUT is the world's (:mod:`evoscen_sim.physics.window`). May import the ground floor, the
configuration, the road, physics and the contract. No ROS here."""
