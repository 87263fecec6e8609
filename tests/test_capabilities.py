"""The capability table (electroloc_gym/contract/capabilities.py): an entry for every env option on every engine,
each engine refusing exactly what the table says it refuses, and the docs' table generated from it.
"""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.contract.capabilities import (  # noqa: E402
    CAPABILITIES,
    CONSTRUCTOR_OPTIONS,
    ENGINES,
    Absent,
    Implemented,
    Limit,
    capability_table_markdown,
    check_engine,
    option_names,
    params_options,
)
from electroloc_gym.contract.params import EnvParams  # noqa: E402
from electroloc_gym.engines.numba_core.electroloc import ElectroLocOptions  # noqa: E402
from electroloc_gym.engines.torch_core.consts import TorchConsts  # noqa: E402
from electroloc_gym.envs import ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.sim_backends import backends_of  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.vector import CoreVectorEnv  # noqa: E402
from electroloc_gym.registry import ENVS, env_entry  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
VECTOR_ENVS = {"numba": CoreVectorEnv, "torch": TorchElectroLocVectorEnv}


def constructor_arguments(cls: type) -> list[str]:
    """The named arguments of a vector env's constructor (not ``self``, not ``**kwargs``)."""
    params = inspect.signature(cls.__init__).parameters.values()
    return [p.name for p in params if p.name != "self" and p.kind is not inspect.Parameter.VAR_KEYWORD]


def missing_entries(fields: list[str], arguments: list[str], table=CAPABILITIES) -> list[str]:
    """Options with no entry, or an entry without every engine."""
    return [name for name in fields + arguments if name not in table or set(table[name]) != set(ENGINES)]


def test_every_option_and_constructor_argument_has_an_entry_for_every_engine():
    fields = list(option_names())
    arguments = sorted({a for cls in VECTOR_ENVS.values() for a in constructor_arguments(cls)})
    assert missing_entries(fields, arguments) == []
    assert set(arguments) == set(CONSTRUCTOR_OPTIONS)  # declared once: the table's list is the signatures'
    assert set(CAPABILITIES) == set(fields) | set(CONSTRUCTOR_OPTIONS)  # and no entry for nothing


def test_the_walk_sees_the_shared_fields_and_every_tasks_options():
    """The options walked are the shared fields and each registered task's ``Options`` fields, once each."""
    names = option_names()
    assert len(names) == len(set(names)) and "options" not in names
    assert set(EnvParams.shared_names()) <= set(names)
    for e in ENVS:
        assert set(e.arguments) <= set(names)
    assert {"target_motion", "layout", "contrast", "sensor_layout", "gain_levels"} <= set(names)


def test_a_new_field_or_option_without_an_entry_fails_the_walk():
    @dataclasses.dataclass(frozen=True)
    class Grown(EnvParams):
        tank_temperature_K: float = 293.0

    assert missing_entries(["task", *Grown.shared_names()], []) == ["tank_temperature_K"]

    @dataclasses.dataclass(frozen=True)
    class GrownOptions(ElectroLocOptions):
        prey_count: int = 1

    assert missing_entries([f.name for f in dataclasses.fields(GrownOptions)], []) == ["prey_count"]
    short = {k: v for k, v in CAPABILITIES.items() if k != "gain_levels"} | {"gain_levels": {"numba": Implemented()}}
    assert missing_entries(["gain_levels"], [], short) == ["gain_levels"]


def test_the_engines_are_the_registered_backends():
    assert tuple(backends_of(env_entry("ElectroLoc-v0"))) == ENGINES


def build(engine: str, **kw):
    """The engine's vector env of ElectroLoc-v0 with ``kw`` (small sizes)."""
    kw = {"num_envs": 2, "n_particles": 20, **kw}
    if engine == "numba":
        return ElectroLocVectorEnv(**kw)
    return TorchElectroLocVectorEnv(**kw)


LIMITS = [(name, e, rule) for name, es in CAPABILITIES.items() for e, rule in es.items() if isinstance(rule, Limit)]
ABSENT = [(name, e, rule) for name, es in CAPABILITIES.items() for e, rule in es.items() if isinstance(rule, Absent)]


@pytest.mark.parametrize(("name", "engine", "rule"), LIMITS, ids=[f"{e}-{n}" for n, e, _ in LIMITS])
def test_each_limit_is_refused_by_its_engine_naming_the_option(name, engine, rule):
    if name == "task":  # set by the env id, not an argument: the engine's constants refuse another task's params
        params = EnvParams.from_kwargs(rule.refused, {}, "another env")
        with pytest.raises(ValueError, match=f"^{name}: backend='torch' takes only {rule.allowed}"):
            TorchConsts.build(params, torch.device("cpu"))
        return
    with pytest.raises(ValueError, match=name):
        build(engine, **{name: rule.refused, **rule.refused_with})
    if engine == "torch":  # the table's own message
        with pytest.raises(ValueError, match=f"^{name}: backend='torch' takes only "):
            build(engine, **{name: rule.refused, **rule.refused_with})


@pytest.mark.parametrize(("name", "engine", "rule"), ABSENT, ids=[f"{e}-{n}" for n, e, _ in ABSENT])
def test_each_absent_option_is_an_unknown_argument_of_its_engine(name, engine, rule):
    value = {"device": "cpu", "compile": False, "compile_backend": "inductor", "action_check": "auto"}.get(name, 1.0)
    with pytest.raises(ValueError, match=f"unexpected argument.*'{name}'"):
        build(engine, **{name: value})


def test_limits_hold_for_the_defaults():
    """The torch engine implements every option at its default: the table refuses nothing of a plain env."""
    options = params_options(EnvParams())
    for engine in ENGINES:
        check_engine(engine, {**options, "render_mode": None, "autoreset_mode": "next_step"})


def test_the_docs_table_is_the_generated_one():
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    table = "\n".join(capability_table_markdown())
    assert table in text, "docs/design.md's engines table differs from capability_table_markdown(): paste it again"
