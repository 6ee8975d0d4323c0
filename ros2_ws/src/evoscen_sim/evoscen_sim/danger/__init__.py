"""Danger: the rules that say when the SUT's state is dangerous (``safety``, the one definition the live
events and the scores share) and the event dicts of a step built on them (``events``). No ROS here."""
