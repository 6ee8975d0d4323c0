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
every bag is still the one before, byte for byte (the hashes 0.6 pinned; Stackelberg's
metadata record gains the rule's key, its messages are 0.6's).

Then, meant to change behaviour: a vehicle that finds no place to enter tries again
``traffic.entry_retry_s`` [1 s] later under both make-ups (``uniform`` tried at every step; docs/method.md
§1). The metadata record gains the key in every bag. Compared per topic with the bags before (3,000
steps, the five runs of each make-up): under ``highd`` every message of all eleven topics is
byte-identical (:data:`HASHES`); under ``uniform`` the worlds change (:data:`UNIFORM_HASHES`), and with
``traffic.entry_retry_s: 0`` every message of all eleven topics is byte-identical to the bags before,
those of 0.6 (:data:`EVERY_STEP_HASHES`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

UNIFORM_HASHES = {  # bvs.makeup: uniform; Stackelberg with target_gap_rule: end_of_game
    None: "916f7ca241a09065f62d57c9d4a6431307af703e0399359ff86bbb48de75f219",  # the shipped default (level0 SUT)
    "nilsson": "430103039a359cb978b9b0c957bb61608e00b3835f37fbdd34a2116c7925d317",
    "mobil": "f349fc07b64483e1fa7c954c0057262209c82e7a5fd4ccda0987b3e1af4fd709",
    "stackelberg": "d4d8f5b09f80cf65641364f730c41fc8431559b6607f2b681f197a4db18b56ec",
    "mutant": "e4ba314de982a5f085b1c22359db54f61d96f4b6a5763eda05f459a046b1a264",  # the default mutant
}

EVERY_STEP_HASHES = {  # the same with traffic.entry_retry_s: 0: every message is 0.6's (compared per topic)
    None: "39814b7b4d805d58b9bc0aa04b496564b183c7002d391856b34ed166aab2d9e8",
    "nilsson": "7415207a42042c8e8211b56a606bfdb21ed71e52225c93bd855ec4d23f0aec5c",
    "mobil": "ce9e2fadb99123509a8a10fad51fd058588ca52615e17476635f7c7f4bd140e1",
    "stackelberg": "947117e0a0fb59d76e94ce16c7106cbb985ab7a39c0b73482d755da88c900ed9",
    "mutant": "320a31b97b0acf4b04b5da6b42dd88b19b4b756dc1c6a896b99050e36d65d3f1",
}


HASHES = {  # the shipped defaults (bvs.makeup: highd, the highd_trained policies)
    None: "18c53b0480788a4a93fb77e2ea07b7e72129b49413780493a8f849f31662103d",  # the shipped default (level0 SUT)
    "nilsson": "1469a2fc63066c1199f58adb8c24c76a3f64569e10a518166ec4e8196decbd16",
    "mobil": "e3c396085a508d871844fe13db166bc10e3ea728e4afec0a7ccd1819aa497c74",
    "stackelberg": "54bf70808f41a1bd88ccdc38d3282546398a95c0783c4f7b9d4423c555f8a3ad",
    "mutant": "bee272419a00bc4b3f2f0b50b44e4fe29319c1397723b144b1af068b708b4049",  # the default mutant
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


@pytest.mark.parametrize("every_step", [False, True], ids=["retry-1s", "retry-every-step"])
@pytest.mark.parametrize("model", list(UNIFORM_HASHES), ids=lambda m: m or "default")
def test_uniform_bags(model: str | None, every_step: bool, tmp_path: Path) -> None:
    overrides = {"bvs.makeup": "uniform"} | ({"sut.model": model} if model else {})
    if model == "stackelberg":
        overrides["models.stackelberg.target_gap_rule"] = "end_of_game"
    if every_step:
        overrides["traffic.entry_retry_s"] = 0
    digest = _digest(overrides, tmp_path)
    want = (EVERY_STEP_HASHES if every_step else UNIFORM_HASHES)[model]
    assert digest == want, f"{model or 'default'} (uniform, every_step={every_step}): the bag changed ({digest})"
