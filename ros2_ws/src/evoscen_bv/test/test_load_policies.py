"""load_policies reads a policy directory once per process and again only when a file it reads changes.

A copy of the shipped directory in a temporary directory; the number of times the training config is
parsed is counted (``load_training_config`` wrapped). The values after a reload are those written
(a decision interval of 7 instead of the shipped 10; a controller whose weights are the shipped ones
times 2), so a stale copy would show.
"""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
from evoscen_bv import learned
from evoscen_bv.learned import CONTROLLER_FILE, POLICY_CODE, POLICY_FILES, load_policies, shipped_policy_dir
from evoscen_sim.errors import InputError


@pytest.fixture()
def policy_dir(tmp_path, monkeypatch):
    src = shipped_policy_dir()
    out = tmp_path / "policies"
    out.mkdir()
    for name in ("training.yaml", CONTROLLER_FILE, *POLICY_FILES.values()):
        shutil.copy(src / name, out / name)
    calls = []
    real = learned.load_training_config
    monkeypatch.setattr(learned, "load_training_config", lambda path: calls.append(path) or real(path))
    return out, calls


def _bump_mtime(path):
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # one second later: a new signature


def test_second_load_of_an_unchanged_directory_parses_nothing_and_shares_the_values(policy_dir):
    out, calls = policy_dir
    c1, d1, t1 = load_policies(out)
    c2, d2, t2 = load_policies(out / ".")  # the same directory by another spelling
    assert len(calls) == 1
    assert c2 is c1 and t2 is t1 and t1.env.decision_interval_steps == 10
    assert d2 == d1 and d2 is not d1  # the same actors in a dict of its own
    assert sorted(d1) == sorted(POLICY_CODE.values())
    with np.load(out / CONTROLLER_FILE) as z:
        np.testing.assert_array_equal(c2.W1, z["W1"])
    with pytest.raises(ValueError):  # shared: read-only
        c1.W1[0, 0] = 1.0


def test_a_rewritten_training_yaml_is_read_again(policy_dir):
    out, calls = policy_dir
    assert load_policies(out)[2].env.decision_interval_steps == 10
    text = (out / "training.yaml").read_text()
    assert "  decision_interval_steps: 10 " in text
    (out / "training.yaml").write_text(text.replace("  decision_interval_steps: 10 ", "  decision_interval_steps: 7 "))
    _bump_mtime(out / "training.yaml")
    assert load_policies(out)[2].env.decision_interval_steps == 7
    assert len(calls) == 2
    _bump_mtime(out / "training.yaml")  # touched only: read again, same values
    assert load_policies(out)[2].env.decision_interval_steps == 7
    assert len(calls) == 3


def test_a_rewritten_weight_file_is_read_again(policy_dir):
    out, calls = policy_dir
    before = load_policies(out)[0].W1.copy()
    with np.load(out / CONTROLLER_FILE) as z:
        weights = {k: z[k] for k in z.files}
    weights["W1"] = 2.0 * weights["W1"]
    np.savez(out / CONTROLLER_FILE, **weights)
    _bump_mtime(out / CONTROLLER_FILE)
    np.testing.assert_array_equal(load_policies(out)[0].W1, 2.0 * before)
    assert len(calls) == 2


def test_failures_are_not_kept(policy_dir, tmp_path):
    out, _ = policy_dir
    load_policies(out)
    os.remove(out / POLICY_FILES["cooperative"])
    for _ in range(2):
        with pytest.raises(InputError, match=r"cooperative\.npz: policy file not found$"):
            load_policies(out)
    missing = tmp_path / "nowhere"
    for _ in range(2):
        with pytest.raises(InputError, match=f"^{missing} is not a directory$"):
            load_policies(missing)
    shutil.copy(shipped_policy_dir() / POLICY_FILES["cooperative"], out / POLICY_FILES["cooperative"])
    assert sorted(load_policies(out)[1]) == sorted(POLICY_CODE.values())
