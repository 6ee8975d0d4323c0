"""Naturalistic room of evoscen_eval: evoscen's traffic measured against data (highD): the aggregates
shipped in ``data/`` (``highd``), the same measures of a run (``highd_export``, ``behaviour``,
``similarity``), fidelity and its checks (``fidelity``, ``fidelity_highd``, ``bv_realism``).
May import the scoring room, the recording, the simulation and the contract."""
