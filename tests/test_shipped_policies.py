"""The shipped policies: each acts as the SB3 model it was exported from, and none holds a pickle.

SB3's ``model.zip`` of a shipped model is not kept (a pickle, and large): ``tests/data/sb3_actions.npz``
holds, per shipped model, fixed observations and the actions SB3's ``predict(obs, deterministic=True)``
gave for them, made once from the zips by ``tests/data/make_sb3_fixture.py`` (its docstring names the
commit that still has them). Most observations give an action SB3 leaves unclipped, so every weight of
the actor shows in it; a few give a clipped one. Needs numpy only: no SB3, torch or pickle.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from electroloc_gym.models import MODELS_DIR, shipped_models
from electroloc_gym.policy import load_policy
from electroloc_gym.policy.format import read_export, read_weights, write_export

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "sb3_actions.npz"
MAKER = "tests/data/make_sb3_fixture.py"
#: The continuous actions' tolerance: the numpy policy computes in float64, SB3 in float32 (the stored
#: actions differ from the numpy policy's by at most 4e-7).
ATOL = 1e-5
#: Files that hold pickles (SB3's zip, VecNormalize's pkl, torch's own files): never in a shipped folder.
PICKLE_SUFFIXES = (".zip", ".pkl", ".pickle", ".pt", ".pth", ".joblib")


def _fixture() -> tuple[dict[str, dict[str, np.ndarray]], dict]:
    with np.load(FIXTURE, allow_pickle=False) as f:
        meta = json.loads(str(f["meta"]))
        entries = {name: {k: f[f"{name}.{k}"] for k in ("obs_q", "actions")} for name in meta["models"]}
    return entries, meta


ENTRIES, META = _fixture()
SHIPPED = sorted(n for n, p in shipped_models().items() if (p / "policy.json").is_file())


def _acts_as_sb3(folder: Path, name: str) -> None:
    """Assert that the policy in ``folder`` gives SB3's stored actions for ``name``'s stored observations."""
    entry = ENTRIES[name]
    obs = entry["obs_q"].astype(np.float32) / np.float32(META["obs_scale"])
    got, _ = load_policy(folder).actor(obs)
    want = entry["actions"]
    where = f"{folder.name}: the numpy policy's actions differ from SB3's stored ones ({FIXTURE.name})"
    if META["models"][name]["weights_sha256"] != read_export(folder).meta["weights"]["sha256"]:
        where += f"; its weights are not those the file was made against: if retrained, run {MAKER}"
    if np.issubdtype(want.dtype, np.integer):
        np.testing.assert_array_equal(got, want, err_msg=where)
    else:
        np.testing.assert_allclose(got, want, rtol=0, atol=ATOL, err_msg=where)


def test_the_fixture_covers_every_shipped_policy():
    assert SHIPPED, "no shipped policy found"
    assert sorted(ENTRIES) == SHIPPED, f"{FIXTURE.name} and the shipped policies differ: run {MAKER} --update"


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_policy_acts_as_its_sb3_model(name):
    entry = ENTRIES[name]
    assert entry["obs_q"].dtype == np.int8 and len(entry["obs_q"]) == len(entry["actions"]) >= 32
    _acts_as_sb3(MODELS_DIR / name, name)


def _actor_tensors(weights: dict[str, np.ndarray]) -> list[str]:
    """The tensors of an SB3 actor-critic's deterministic action (its policy branch and action head)."""
    return sorted(k for k in weights if k.startswith(("mlp_extractor.policy_net.", "action_net.")))


@pytest.mark.parametrize("delta", [1e-3, -1e-3])
def test_one_changed_weight_fails_the_comparison(tmp_path, delta):
    """The check has power: one weight of the actor changed by ``delta`` (files still consistent) fails it."""
    name = "ppo-belief"
    folder = tmp_path / name
    shutil.copytree(MODELS_DIR / name, folder)
    export = read_export(folder)
    weights = read_weights(export)
    meta = {k: v for k, v in export.meta.items() if k != "weights"}
    names = _actor_tensors(weights)
    assert len(names) == 6, names  # two hidden layers and the action head, weight and bias each
    for tensor in names:
        changed = {k: v.copy() for k, v in weights.items()}
        flat = changed[tensor].reshape(-1)
        flat[int(np.argmax(np.abs(flat)))] += delta
        write_export(folder, meta, changed)
        with pytest.raises(AssertionError, match="differ from SB3's"):
            _acts_as_sb3(folder, name)
    write_export(folder, meta, weights)  # the unchanged weights pass again
    _acts_as_sb3(folder, name)


def test_shipped_policies_hold_no_pickle():
    """A shipped folder holds the pickle-free format and provenance only: no SB3 zip, no VecNormalize pkl."""
    for name, folder in shipped_models().items():
        pickles = sorted(p.name for p in folder.rglob("*") if p.suffix.lower() in PICKLE_SUFFIXES)
        assert not pickles, f"electroloc_gym/models/{name}/ holds pickles: {pickles}"
        assert (folder / "policy.json").is_file() and (folder / "policy.safetensors").is_file(), name
        assert load_policy(folder).env_kwargs["observation"] in ("belief", "raw")
