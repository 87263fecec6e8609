"""policy.json's types: every field of the schema is read with its JSON type checked, so a value of the wrong type
(``"norm_obs": "yes"``, a boolean version, a string size) is one PolicyFormatError naming the file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from electroloc_gym.policy import PolicyFormatError, load_policy
from electroloc_gym.policy.format import POLICY_KWARGS

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "electroloc_gym" / "models" / "ppo-belief"


def _copy(tmp_path: Path, edit) -> Path:
    d = tmp_path / "policy"
    shutil.copytree(SHIPPED, d)
    meta = json.loads((d / "policy.json").read_text(encoding="utf-8"))
    edit(meta)
    (d / "policy.json").write_text(json.dumps(meta), encoding="utf-8")
    return d


def _set(*path_and_value):
    *path, value = path_and_value

    def edit(meta):
        node = meta
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value

    return edit


@pytest.mark.parametrize(
    "edit,pattern",
    [
        (_set("normalization", "norm_obs", "yes"), r"normalization\.norm_obs must be true or false, got 'yes'"),
        (_set("normalization", "norm_obs", 1), r"normalization\.norm_obs must be true or false, got 1"),
        (_set("normalization", "norm_reward", "no"), r"normalization\.norm_reward must be true or false"),
        (_set("normalization", "clip_obs", "10"), r"normalization\.clip_obs must be a finite number"),
        (_set("normalization", "clip_reward", True), r"normalization\.clip_reward must be a finite number"),
        (_set("normalization", "gamma", [0.99]), r"normalization\.gamma must be a finite number"),
        (_set("normalization", "obs_count", "many"), r"normalization\.obs_count must be a finite number or null"),
        (_set("normalization", "obs_mean", "0"), r"normalization\.obs_mean must be a list of numbers or null"),
        (_set("format_version", True), "format_version True is not supported"),
        (_set("format_version", 1.0), "format_version 1.0 is not supported"),
        (_set("weights", "sha256", "ABC"), "weights.sha256 must be 64 lowercase hex digits"),
        (_set("weights", "tensors", "8"), r"weights\.tensors must be an integer ≥ 0"),
        (_set("algo", ""), "algo must be a non-empty string"),
        (_set("architecture", "policy_kwargs", "net_arch", ["128"]), r"policy_kwargs\.net_arch must be a list"),
        (_set("architecture", "policy_kwargs", "net_arch", {"pi": [0]}), r"policy_kwargs\.net_arch must be"),
        (_set("architecture", "policy_kwargs", "log_std_init", "low"), r"policy_kwargs\.log_std_init must be a"),
        (_set("architecture", "policy_kwargs", "use_sde", "false"), r"policy_kwargs\.use_sde must be true or false"),
        (
            _set("architecture", "policy_kwargs", "optimizer_class", "os.system"),
            r"unknown key\(s\) \['optimizer_class'\]",
        ),
        (_set("architecture", "recurrent", {"lstm_hidden_size": 8}), "recurrent must be null for a ActorCriticPolicy"),
        (_set("observation", "env_id", ""), "observation.env_id must be a non-empty string"),
        (_set("observation", "frame_stack", True), "'frame_stack' has the wrong type"),
        (_set("action", "action_type", "discrete"), "action.action_type must be one of"),
        (_set("action", "action_type", "yes"), "action.action_type must be one of"),
        (_set("env_kwargs", ["observation"]), "env_kwargs must be an object"),
        (_set("provenance", "trained"), "provenance must be an object"),
        (_set("evaluation", 3), "evaluation must be an object or null"),
    ],
)
def test_a_field_of_the_wrong_type_is_one_error_naming_the_file(tmp_path, edit, pattern):
    d = _copy(tmp_path, edit)
    with pytest.raises(PolicyFormatError, match=pattern) as exc:
        load_policy(d)
    assert str(d / "policy.json") in str(exc.value) and "\n" not in str(exc.value)


def test_a_recurrent_policy_class_needs_its_lstm_fields(tmp_path):
    d = _copy(tmp_path, _set("architecture", "policy_class", "RecurrentActorCriticPolicy"))
    with pytest.raises(PolicyFormatError, match="recurrent of a RecurrentActorCriticPolicy must be an object"):
        load_policy(d)
    lstm = {"lstm_hidden_size": 8, "n_lstm_layers": "1", "shared_lstm": False, "enable_critic_lstm": True}
    d = _copy(
        tmp_path / "b",
        lambda m: m["architecture"].update(policy_class="RecurrentActorCriticPolicy", recurrent=lstm),
    )
    with pytest.raises(PolicyFormatError, match=r"recurrent\.n_lstm_layers must be an integer ≥ 1"):
        load_policy(d)


def test_the_shipped_policies_and_every_declared_kind_load(tmp_path):
    agent = load_policy(SHIPPED)
    assert agent.normalization is not None
    assert set(json.loads((SHIPPED / "policy.json").read_text())["architecture"]["policy_kwargs"]) <= set(POLICY_KWARGS)
    d = _copy(tmp_path, _set("normalization", "obs_count", None))  # null statistics counts are allowed
    action, _ = load_policy(d).predict(np.zeros(81, dtype=np.float32))
    assert np.isfinite(action).all()
    d = _copy(tmp_path / "b", _set("normalization", "norm_obs", False))  # a real false: no normalisation
    assert load_policy(d).normalization is None
