"""Danger: the rules that say when the SUT's state is dangerous (``safety``, the one definition the live
events and the scores share) and the event dicts of a step built on them (``events``). May import the
ground floor, the configuration, the road, physics and the contract; nothing of traffic or the loop.
No ROS here."""
