"""Refactoring guard (issue 15): the bags of the default scenario and of each SUT model over 3,000
steps, in-process, must keep their SHA-256. A change that alters a single byte of a bag fails
here; a change meant to alter behaviour updates the hashes in its own commit and says why.

History: the hashes of commit 76c0247 (before the architecture work) held through the
refactorings until ``evaluation.rear_braking`` (issue 17): the scenario metadata record gained
its two keys and some ``evoscen/exposure`` events changed; the world, command, clock and
odometry messages stayed identical to the byte (compared per topic). Then, meant to change
behaviour (issue 17, evaluation and BV changes): the learned BVs' lane hold
(``models.learned.lane_hold_s``: the world changes), cut-ins and the ``conflict`` reading of
hard braking (``evaluation.cut_in_gap_m``, ``evaluation.hard_braking``: the metadata record
and the ``evoscen/exposure`` events change). Then the ``driver`` profile's emergency brake
acts at once for a perceived leader at rest (``models.learned.standing_leader_at_once``; with it
false the earlier hashes held, checked), and the shipped BV set was retrained (docs/learned-bvs.md).
Then a lane change beside a vehicle is dangerous (``evaluation.beside_lane_change``,
docs/evaluation.md §3.7): the metadata record gains the key in every bag, and the default mutant's
``evoscen/events`` change (its exposure events); every other message of the five runs is byte-identical
to the bags before (compared per topic). Then ``evaluation.count_normalisation`` and
``evaluation.count_reference_steps`` (docs/evaluation.md §1.1): the metadata record gains the two
keys in every bag; every message of the five runs is byte-identical to the bags before (compared
per topic: all nine topics). Then, meant to change behaviour: the traffic window with its warm-up
(``traffic.mode: window``, docs/method.md §1), the learned BVs' merge rules
(``models.learned.into_ending_lane``, ``forced_merge_m``) and the rule-based BVs' speed factors
(``models.krauss.speed_factor_sd``): every world changes. With ``traffic.mode: loop`` and the three
keys at their earlier values the earlier design drives as before: tests/test_profiles.py checks
every command of 400 steps that way (not the whole bags: their metadata record lists the new keys).
Then, meant to change behaviour: a learned BV that must merge adapts its speed to a gap
(``models.learned.merge_seek``, docs/learned-bvs.md, "Merging"): the worlds change wherever a BV
is on the merge lane beside traffic; and a learned BV that enters anew starts with the lane hold
(``models.learned.hold_on_entry``, "Lane hold"); the metadata record gains both keys.
Then ``evaluation.ssm_ttc_threshold_s`` and ``evaluation.ssm_pet_threshold_s`` (the surrogate-safety
profile, docs/evaluation.md; read by the evaluator only): the metadata record gains the two keys in
every bag; every message of the default and the default mutant's runs is byte-identical to the bags
before (compared per topic: all nine topics, and the recorded scenario differs only by the two keys).
Then the learned BVs' hard braking of the SUT's leader (``models.learned.hard_brake`` and the
``hard_brake_*`` keys, docs/learned-bvs.md, "Hard braking"): the metadata record gains the keys in
every bag; no episode starts in the five runs, and every message of the default and the default
mutant's runs is byte-identical between ``hard_brake`` true and false (compared per topic: all nine
topics); with it false every command of 1,000 steps equals the code before (test_hard_brake.py).
Then BV nodes (``bvs.nodes``, docs/architecture.md §5, "BV nodes"): the metadata record gains the key
in every bag, and with the default ``by_policy`` the BV commands go out on one topic per BV node
(``/evoscen/commands/bv_competitive``, ``_mutual``, ``_cooperative``) instead of ``/evoscen/commands/bv``.
Compared per topic with the bags before, default scenario, 3,000 steps: with ``bvs.nodes: single``
every message of all nine topics is byte-identical; with ``by_policy`` every message of the eight
other topics is (the world does not depend on the split).

Then the tailgating rule (``evaluation.headway_threshold_s``, docs/evaluation.md §2 item 6: the
metadata record gains the key, the default mutant's exposure events change) and the hard braking of
the SUT's leader with its episodes drawn per vehicle (``models.learned.hard_brake*``), with the BV
nodes of ``bvs.nodes`` (their command topics): regenerated after merging them together; then the
tailgating rule's grace (``evaluation.headway_grace_s``: the metadata record, the mutant's exposures).

The hashes hold on the machines this project tests on (x86-64, the pinned numpy/numba); the
kernels' floating-point results could differ on another CPU family.
Then, meant to change behaviour: competitive learned BVs do not yield to the SUT's lane-change intent
(``models.learned.competitive_cut_in: compete``, docs/learned-bvs.md): the worlds of every SUT that changes
lanes change; the default's bag (a level-0 SUT, which never changes lanes) stays byte-identical, and
with ``yield`` every command of 1,000 steps equals the code before (test_competitive_cut_in.py).

Then, meant to change behaviour (0.7.0): ``bvs.makeup: highd`` became the default (cars and trucks as in
highD, the ``highd_trained`` policies; docs/bv-profiles.md), trucks are coloured as trucks in the
markers, and Stackelberg honours d_min to the target lane's vehicles now
(``models.stackelberg.target_gap_rule: d_min_now``, docs/method.md §4.3). The defaults' hashes are new
(:data:`HASHES`); with ``bvs.makeup: uniform`` (and ``target_gap_rule: end_of_game`` for Stackelberg)
every bag is still the one before, byte for byte (:data:`UNIFORM_HASHES`, the hashes 0.6 pinned; Stackelberg's
metadata record gains the rule's key, its messages are 0.6's).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

UNIFORM_HASHES = {  # bvs.makeup: uniform; Stackelberg with target_gap_rule: end_of_game (the bags of 0.6)
    None: "15dd1faa6d268ba0a7582fa2c2a3856b5acffd7d5b2e65ccfcc3e1ecbd0a0d2d",  # the shipped default (level0 SUT)
    "nilsson": "87733d380065fff56a64841982664fcb0f3393cb43c9dc6670ea698cca26fbd1",
    "mobil": "390fcf8e339c4a1a8b7ea90ea246a4042fbf6d0b1558c3e279b6cf6258347822",
    # the metadata record gains models.stackelberg.target_gap_rule; every message of all eleven topics is
    # byte-identical to 0.6's bag (3acc408f…, compared per topic)
    "stackelberg": "e5996a6b4b9cb55ddcc6cab553ad10f078ea8f0cc22d69b3767550dd93638b4c",
    "mutant": "93b5fedcac7343512a4b270a815fb38e03b7656584505ec7042ec5dbeee85910",  # the default mutant
}


HASHES = {  # the shipped defaults (bvs.makeup: highd, the highd_trained policies; evoscen 0.7.0)
    None: "99c839de31c5f68a88f823c85f5ebfff41c5e376f23be396b4f6d6a8a1cef52f",  # the shipped default (level0 SUT)
    "nilsson": "25f6ac1b5cfea1deedfaa20547b36bc87ff4c70c65f3a69e4a165423a62bc72e",
    "mobil": "d536a6fa811bed1435f95fa79aa5b78c2f18c374566a3399f3238f1ebfb8cba7",
    "stackelberg": "3d8d4cd514231a9b444b1c53fac49494dd04ed02fae43c3c233eb542a2c37c82",
    "mutant": "3601aa7e6fdfde30f925519e415472abdf9b7ee889470f3a6e57b7ad8bcf2c33",  # the default mutant
}


def _digest(overrides: dict, tmp_path: Path) -> str:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    run_inprocess(load_scenario_config(None, {"steps": 3000} | overrides), bag_dir=tmp_path / "bag", evaluate=False)
    return hashlib.sha256((tmp_path / "bag" / "bag_0.mcap").read_bytes()).hexdigest()


@pytest.mark.parametrize("model", list(HASHES), ids=lambda m: m or "default")
def test_bag_bytes_unchanged(model: str | None, tmp_path: Path) -> None:
    digest = _digest({"sut.model": model} if model else {}, tmp_path)
    assert digest == HASHES[model], f"{model or 'default'}: the bag changed ({digest})"


@pytest.mark.parametrize("model", list(UNIFORM_HASHES), ids=lambda m: m or "default")
def test_uniform_bags_are_those_of_0_6(model: str | None, tmp_path: Path) -> None:
    overrides = {"bvs.makeup": "uniform"} | ({"sut.model": model} if model else {})
    if model == "stackelberg":
        overrides["models.stackelberg.target_gap_rule"] = "end_of_game"
    digest = _digest(overrides, tmp_path)
    assert digest == UNIFORM_HASHES[model], f"{model or 'default'} (uniform): the bag changed ({digest})"
