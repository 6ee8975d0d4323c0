"""The graph's nodes: the simulation node, the BV and SUT nodes' controller node, node parameters, which
BVs each BV node hosts. May import anything of evoscen_sim and the contract (rclpy through it)."""
