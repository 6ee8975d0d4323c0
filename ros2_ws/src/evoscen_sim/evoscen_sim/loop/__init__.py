"""The loop and what it hands the drivers: the one step loop both runners drive (``step_loop``), the
traffic view a driver decides from (``view``) and worlds built by hand to try a driver (``hand_built``).
May import every room of evoscen_sim and the contract. No ROS here."""
