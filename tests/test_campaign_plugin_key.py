"""Campaign run keys cover the plug-in a run uses (evoscen_experiments.campaign_spec.run_key, docs/campaigns.md
"Each run once"): a changed plug-in file or version gives new keys, a run without a plug-in keeps
the key of the configuration and code version alone.

The plug-in is a temporary copy of examples/first_sut made visible as an installed distribution
(a ``.dist-info`` with its entry point beside the module, on PYTHONPATH of a subprocess), so
nothing is installed into the environment."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = r"""
import hashlib, json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import _bootstrap  # noqa: F401
from evoscen_experiments import campaign_spec as C
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.config.config_load import config_to_dict

module, metadata = Path(sys.argv[2]), Path(sys.argv[3])
CONFIGS = {"plugin": {"sut.model": "first_sut"}, "builtin": {"sut.model": "mobil"},
           "mutant": {"sut.model": "mutant", "models.mutant.base": "first_sut", "models.mutant.operator": "blind_behind"}}

def state():
    C.plugin_fingerprint.cache_clear()
    out = {}
    for name, over in CONFIGS.items():
        cfg = load_scenario_config(None, {**over, "steps": "10", "seed": "4"})
        d = config_to_dict(cfg)
        out[name] = {"key": C.run_key(cfg, "v1"), "plugins": C.plugin_versions(d),
                     "plain": hashlib.sha256(("v1\n" + json.dumps(d, sort_keys=True, default=str)).encode()).hexdigest()[:20]}
    return out

original = module.read_bytes()
states = {"original": state()}
module.write_bytes(original + b"\n# an edit of the plug-in\n")
states["edited"] = state()
module.write_bytes(original)
states["restored"] = state()
metadata.write_text(metadata.read_text().replace("Version: 0.1.0", "Version: 0.2.0"))
states["new_version"] = state()
print(json.dumps(states))
"""


def test_plugin_edit_and_version_change_the_key(tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    module = site / "first_sut.py"
    shutil.copy(ROOT / "examples" / "first_sut" / "first_sut.py", module)
    info = site / "evoscen_first_sut_copy-0.1.0.dist-info"
    info.mkdir()
    metadata = info / "METADATA"
    metadata.write_text("Metadata-Version: 2.1\nName: evoscen-first-sut-copy\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[evoscen.sut]\nfirst_sut = first_sut:SPEC\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH", "")) if p)}
    p = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT / "scripts"), str(module), str(metadata)],
                       env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    s = json.loads(p.stdout.strip().splitlines()[-1])

    def fingerprint(content: bytes, version: str) -> str:  # the rule of campaign_spec.plugin_fingerprint
        h = hashlib.sha256(b"first_sut.py" + hashlib.sha256(content).digest()).hexdigest()[:16]
        return f"first_sut=evoscen-first-sut-copy=={version}:{h}"

    original = module.read_bytes()
    edited = original + b"\n# an edit of the plug-in\n"
    assert s["original"]["plugin"]["plugins"] == fingerprint(original, "0.1.0")
    assert s["edited"]["plugin"]["plugins"] == fingerprint(edited, "0.1.0")
    assert s["new_version"]["plugin"]["plugins"] == fingerprint(original, "0.2.0")
    # the key covers it: an edit or a new version gives a new key; the original file its old key
    keys = {name: s[name]["plugin"]["key"] for name in s}
    assert len({keys["original"], keys["edited"], keys["new_version"]}) == 3
    assert keys["restored"] == keys["original"]
    # a mutant of the plug-in (models.mutant.base) too
    mutant = {name: s[name]["mutant"]["key"] for name in s}
    assert s["original"]["mutant"]["plugins"] == fingerprint(original, "0.1.0")
    assert mutant["edited"] != mutant["original"] == mutant["restored"] != mutant["new_version"]
    # a run without a plug-in: no plug-in part, the key of configuration and code version alone
    for name in s:
        assert s[name]["builtin"]["plugins"] == ""
        assert s[name]["builtin"]["key"] == s[name]["builtin"]["plain"] == s["original"]["builtin"]["plain"]
        assert s[name]["plugin"]["key"] != s[name]["plugin"]["plain"]
