"""policy.json's structure and types, checked at load: a value of the wrong type (``"norm_obs": "yes"``, a boolean
version, a string size), a missing or unknown field, or tensors that are not those the declared architecture builds
is one PolicyFormatError naming the file and the field; every committed policy loads and acts as its files say."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from electroloc_gym.policy import PolicyFormatError, load_policy
from electroloc_gym.policy.format import ALGOS, POLICY_KWARGS, normalization_from_json, write_export
from electroloc_gym.policy.load import LearnedAgent

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "electroloc_gym" / "models" / "ppo-belief"
TRACK = ROOT / "electroloc_gym" / "models" / "ppo-belief-track"


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
        (_set("normalization", "norm_obs", "yes"), r"Expected `bool`, got `str` - at `\$\.normalization\.norm_obs`"),
        (_set("normalization", "norm_obs", 1), r"Expected `bool`, got `int` - at `\$\.normalization\.norm_obs`"),
        (
            _set("normalization", "norm_reward", "no"),
            r"Expected `bool`, got `str` - at `\$\.normalization\.norm_reward`",
        ),
        (_set("normalization", "clip_obs", "10"), r"Expected `float`, got `str` - at `\$\.normalization\.clip_obs`"),
        (
            _set("normalization", "clip_reward", True),
            r"Expected `float`, got `bool` - at `\$\.normalization\.clip_reward`",
        ),
        (_set("normalization", "gamma", [0.99]), r"Expected `float`, got `array` - at `\$\.normalization\.gamma`"),
        (
            _set("normalization", "obs_count", "many"),
            r"Expected `float \| null`, got `str` - at `\$\.normalization\.obs_count`",
        ),
        (
            _set("normalization", "obs_mean", "0"),
            r"Expected `array \| null`, got `str` - at `\$\.normalization\.obs_mean`",
        ),
        (_set("format_version", True), r"Expected `int`, got `bool` - at `\$\.format_version`"),
        (_set("format_version", 1.0), r"Expected `int`, got `float` - at `\$\.format_version`"),
        (
            _set("weights", "sha256", "ABC"),
            r"Expected `str` matching regex '\^\[0-9a-f\]\{64\}\$' - at `\$\.weights\.sha256`",
        ),
        (_set("weights", "tensors", "8"), r"Expected `int`, got `str` - at `\$\.weights\.tensors`"),
        (_set("algo", ""), r"Expected `str` of length >= 1 - at `\$\.algo`"),
        (
            _set("architecture", "policy_kwargs", "net_arch", ["128"]),
            r"Expected `int`, got `str` - at `\$\.architecture\.policy_kwargs\.net_arch\[0\]`",
        ),
        (
            _set("architecture", "policy_kwargs", "net_arch", {"pi": [0]}),
            r"Expected `int` >= 1 - at `\$\.architecture\.policy_kwargs\.net_arch\.pi\[0\]`",
        ),
        (
            _set("architecture", "policy_kwargs", "log_std_init", "low"),
            r"Expected `float`, got `str` - at `\$\.architecture\.policy_kwargs\.log_std_init`",
        ),
        (
            _set("architecture", "policy_kwargs", "use_sde", "false"),
            r"Expected `bool`, got `str` - at `\$\.architecture\.policy_kwargs\.use_sde`",
        ),
        (
            _set("architecture", "policy_kwargs", "optimizer_class", "os.system"),
            r"Object contains unknown field `optimizer_class` - at `\$\.architecture\.policy_kwargs`",
        ),
        (
            _set(
                "architecture",
                "recurrent",
                {"lstm_hidden_size": 8, "n_lstm_layers": 1, "shared_lstm": False, "enable_critic_lstm": True},
            ),
            "recurrent must be null for a ActorCriticPolicy",
        ),
        (_set("architecture", "recurrent", {"lstm_hidden_size": 8}), r"missing required field `n_lstm_layers`"),
        (_set("observation", "env_id", ""), r"Expected `str` of length >= 1 - at `\$\.observation\.env_id`"),
        (_set("observation", "frame_stack", True), r"Expected `int`, got `bool` - at `\$\.observation\.frame_stack`"),
        (_set("action", "action_type", "discrete"), "action.action_type must match the action space"),
        (
            _set("action", "action_type", "yes"),
            r"action\.action_type must be one of \['continuous', 'discrete'\], got 'yes'",
        ),
        (_set("env_kwargs", ["observation"]), r"Expected `object`, got `array` - at `\$\.env_kwargs`"),
        (_set("provenance", "trained"), r"Expected `object`, got `str` - at `\$\.provenance`"),
        (_set("evaluation", 3), r"Expected `object \| null`, got `int` - at `\$\.evaluation`"),
    ],
)
def test_a_field_of_the_wrong_type_is_one_error_naming_the_file(tmp_path, edit, pattern):
    d = _copy(tmp_path, edit)
    with pytest.raises(PolicyFormatError, match=pattern) as exc:
        load_policy(d)
    assert str(d / "policy.json") in str(exc.value) and "\n" not in str(exc.value)


def test_a_recurrent_policy_class_needs_its_lstm_fields(tmp_path):
    def recurrent(m):
        m["algo"], m["architecture"]["policy_class"] = "recurrentppo", "RecurrentActorCriticPolicy"

    d = _copy(tmp_path, recurrent)
    with pytest.raises(PolicyFormatError, match="recurrent of a RecurrentActorCriticPolicy must be an object"):
        load_policy(d)
    lstm = {"lstm_hidden_size": 8, "n_lstm_layers": "1", "shared_lstm": False, "enable_critic_lstm": True}
    d = _copy(tmp_path / "b", lambda m: (recurrent(m), m["architecture"].update(recurrent=lstm)))
    with pytest.raises(
        PolicyFormatError, match=r"Expected `int`, got `str` - at `\$\.architecture\.recurrent\.n_lstm_layers`"
    ):
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


# ---- damage of any part: one error at load naming the file and the field -------------------------------------
def _drop(*path):
    def edit(meta):
        node = meta
        for k in path[:-1]:
            node = node[k]
        del node[path[-1]]

    return edit


def _tensors(fn, count=None):
    """A tensor edit (``fn(tensors)`` in place), the sha256 updated to the new file (the damage a check of the
    hash cannot see), and ``weights.tensors`` set to the new count unless ``count`` says otherwise."""
    return ("tensors", fn, count)


def _reshape(name, shape):
    return lambda t: t.__setitem__(name, np.zeros(shape, dtype=np.float32))


def _copy_damaged(tmp_path: Path, damage) -> Path:
    import safetensors.numpy as st

    d = tmp_path / "policy"
    shutil.copytree(TRACK, d)
    meta = json.loads((d / "policy.json").read_text(encoding="utf-8"))
    if isinstance(damage, bytes):  # a weights file that is no safetensors file, its sha256 recorded
        (d / "policy.safetensors").write_bytes(damage)
        meta["weights"]["sha256"] = hashlib.sha256(damage).hexdigest()
    elif isinstance(damage, tuple) and damage[0] == "tensors":
        _, fn, count = damage
        tensors = st.load_file(str(d / "policy.safetensors"))
        fn(tensors)
        blob = st.save(tensors)
        (d / "policy.safetensors").write_bytes(blob)
        meta["weights"].update(
            sha256=hashlib.sha256(blob).hexdigest(), tensors=len(tensors) if count is None else count
        )
    else:
        damage(meta)
    (d / "policy.json").write_text(json.dumps(meta), encoding="utf-8")
    return d


#: One row per damage of a shipped policy's folder: (the damage, what the one error names).
DAMAGES = {
    "missing normalization": (_drop("normalization"), r"Object missing required field `normalization`"),
    "normalization without norm_obs": (
        _drop("normalization", "norm_obs"),
        r"missing required field `norm_obs` - at `\$\.normalization`",
    ),
    "norm_obs without clip_obs": (
        _drop("normalization", "clip_obs"),
        r"norm_obs is true but \['clip_obs'\] are missing",
    ),
    "norm_obs without epsilon": (_drop("normalization", "epsilon"), r"norm_obs is true but \['epsilon'\] are missing"),
    "a misspelt top-level key": (
        lambda m: m.update(normalisation=m.pop("normalization")),
        r"Object contains unknown field `normalisation`",
    ),
    "wrong tensor count": (_set("weights", "tensors", 12), r"weights\.tensors is 12, but policy\.safetensors holds 13"),
    "missing tensor count": (
        _drop("weights", "tensors"),
        r"Object missing required field `tensors` - at `\$\.weights`",
    ),
    "unknown weights key": (
        _set("weights", "dtype", "float32"),
        r"Object contains unknown field `dtype` - at `\$\.weights`",
    ),
    "wrong net_arch": (
        _set("architecture", "policy_kwargs", "net_arch", [64, 64]),
        r"net_arch \[64, 64\].*'mlp_extractor\.policy_net\.0\.weight' has shape \(128, 81\), "
        r"the architecture's is \(64, 81\)",
    ),
    "one layer too many in net_arch": (
        _set("architecture", "policy_kwargs", "net_arch", [128, 128, 128]),
        r"net_arch \[128, 128, 128\].*missing \['mlp_extractor\.policy_net\.4\.bias'",
    ),
    "net_arch of the critic's form": (
        _set("architecture", "policy_kwargs", "net_arch", {"pi": [128, 128], "qf": [128, 128]}),
        r"net_arch of a ActorCriticPolicy must be a list of layer sizes or \{'pi', 'vf'",
    ),
    "missing net_arch": (_drop("architecture", "policy_kwargs", "net_arch"), r"policy_kwargs\.net_arch is missing"),
    "unknown algo": (_set("algo", "ppo2"), r"algo must be one of \[.*'ppo'.*\], got 'ppo2'"),
    "algo of another policy class": (
        _set("algo", "sac"),
        r"algo 'sac' goes with architecture\.policy_class 'SACPolicy'",
    ),
    "gSDE": (_set("architecture", "policy_kwargs", "use_sde", True), r"policy_kwargs\.use_sde must be false"),
    "LSTM keys without an LSTM": (
        _set("architecture", "policy_kwargs", "lstm_hidden_size", 8),
        r"policy_kwargs holds LSTM keys \['lstm_hidden_size'\]",
    ),
    "missing recurrent": (
        _drop("architecture", "recurrent"),
        r"Object missing required field `recurrent` - at `\$\.architecture`",
    ),
    "unknown observation mode": (
        _set("observation", "mode", "image"),
        r"observation\.mode must be one of \['belief', 'raw'\], got 'image'",
    ),
    "unknown observation key": (
        _set("observation", "dtype", "float32"),
        r"Object contains unknown field `dtype` - at `\$\.observation`",
    ),
    "unknown action key": (_set("action", "n", 2), r"Object contains unknown field `n` - at `\$\.action`"),
    "no safetensors file, with its sha256": (
        b"\xff" * 64,
        r"policy\.safetensors is not a readable safetensors file: SafetensorError: .{1,200}$",
    ),
    "missing value-net tensor": (
        _tensors(lambda t: t.pop("value_net.weight")),
        r"tensors of policy\.safetensors do not fit .*: missing \['value_net\.weight'\]",
    ),
    "missing value-net tensor, count unchanged": (
        _tensors(lambda t: t.pop("value_net.weight"), count=13),
        r"weights\.tensors is 13, but policy\.safetensors holds 12",
    ),
    "extra tensor": (
        _tensors(lambda t: t.__setitem__("extra.weight", np.zeros(3, np.float32))),
        r"not of this architecture \['extra\.weight'\]",
    ),
    "wrong-shaped tensor with a correct sha256": (
        _tensors(_reshape("mlp_extractor.policy_net.0.weight", (128, 80))),
        r"'mlp_extractor\.policy_net\.0\.weight' has shape \(128, 80\), the architecture's is \(128, 81\)",
    ),
    "wrong-shaped action head": (
        _tensors(_reshape("action_net.weight", (3, 128))),
        r"observation\.shape \[81\], action\.space Box\(2,\): 'action_net\.weight' has shape \(3, 128\)",
    ),
    "integer tensor": (
        _tensors(lambda t: t.__setitem__("log_std", np.zeros(2, np.int32))),
        r"'log_std' is int32, not floating-point",
    ),
}


@pytest.mark.parametrize("damage,says", list(DAMAGES.values()), ids=list(DAMAGES))
def test_any_damage_is_one_error_at_load_naming_the_file_and_the_field(tmp_path, damage, says):
    d = _copy_damaged(tmp_path, damage)
    with pytest.raises(PolicyFormatError, match=says) as info:
        load_policy(d)
    text = str(info.value)
    assert text.startswith((str(d / "policy.json"), str(d / "policy.safetensors"))) and "\n" not in text, text


def test_no_normalisation_is_said_explicitly(tmp_path):
    """A policy that reads raw observations says so (``"normalization": null`` or ``norm_obs`` false)."""
    for k, edit in enumerate((_set("normalization", None), _set("normalization", {"norm_obs": False}))):
        agent = load_policy(_copy_damaged(tmp_path / str(k), edit))
        assert agent.normalization is None


def _committed_policies() -> list[Path]:
    return sorted(
        p.parent
        for p in [
            *(ROOT / "electroloc_gym" / "models").glob("*/policy.json"),
            *(ROOT / "experiments").rglob("policy.json"),
        ]
    )


def test_every_committed_policy_loads_and_acts_as_its_files_say():
    """Every shipped policy (and every kept one under experiments/) passes the checks, and acts exactly as the
    network its files hold, read without them (the same actions, bit for bit, on fixed observations)."""
    import safetensors.numpy as st

    folders = _committed_policies()
    assert len([f for f in folders if f.parent.name == "models"]) == 8
    for folder in folders:
        agent = load_policy(folder)
        meta = json.loads((folder / "policy.json").read_text(encoding="utf-8"))
        assert meta["algo"] in ALGOS and "normalization" in meta
        norm = normalization_from_json(meta["normalization"], meta["observation"], "raw")
        raw = LearnedAgent(meta, st.load_file(str(folder / "policy.safetensors")), norm, "raw")
        rng = np.random.default_rng(0)
        for step in range(3):
            obs = rng.uniform(-1, 1, (4, agent.obs_dim)).astype(np.float32)
            start = np.full(4, step == 0)
            got, want = agent.predict(obs, episode_start=start)[0], raw.predict(obs, episode_start=start)[0]
            assert got.dtype == want.dtype and np.array_equal(got, want), folder


def test_a_writer_cannot_leave_a_policy_that_does_not_load(tmp_path):
    import safetensors.numpy as st

    meta = json.loads((TRACK / "policy.json").read_text(encoding="utf-8"))
    meta.pop("weights")
    tensors = st.load_file(str(TRACK / "policy.safetensors"))
    write_export(tmp_path / "ok", meta, tensors)
    assert load_policy(tmp_path / "ok").normalization is not None
    for name, (m, t, says) in {
        "no normalization": ({k: v for k, v in meta.items() if k != "normalization"}, tensors, "`normalization`"),
        "no value net": (meta, {k: v for k, v in tensors.items() if k != "value_net.bias"}, "value_net.bias"),
    }.items():
        with pytest.raises(PolicyFormatError, match=f"refusing to write a policy that would not load: .*{says}"):
            write_export(tmp_path / name, m, t)
        assert not (tmp_path / name).exists()


def test_an_actor_only_file_says_it_has_no_stochastic_actions():
    folder = next(f for f in _committed_policies() if json.loads((f / "policy.json").read_text())["algo"] == "bc")
    agent = load_policy(folder)
    obs = np.zeros(agent.obs_dim, dtype=np.float32)
    assert np.isfinite(agent.predict(obs)[0]).all()
    with pytest.raises(ValueError, match="holds the deterministic actor alone"):
        agent.predict(obs, deterministic=False)
