"""The one KEY=VALUE syntax: agent spec options, ``electroloc train``'s and the learned suite's overrides."""

from __future__ import annotations

import pytest

from electroloc_gym.utils.agentspec import parse_agent_spec, parse_options


def test_values_by_the_agent_spec_rule() -> None:
    got = parse_options(
        ["n_envs=8", "learning_rate=3e-4", "condition=fresh-steel-12.7", "net=[64,64]", "flag=True", "name='a b'"],
        "--hyperparams",
    )
    assert got == {
        "n_envs": 8,
        "learning_rate": 3e-4,
        "condition": "fresh-steel-12.7",
        "net": [64, 64],
        "flag": True,
        "name": "a b",
    }
    assert parse_agent_spec("x[n_envs=8,condition=fresh-steel-12.7]").options == parse_options(
        ["n_envs=8", "condition=fresh-steel-12.7"], "w"
    )
    assert parse_options([], "--env-kwargs") == {}


@pytest.mark.parametrize(
    "items, words",
    [
        (["observation"], "--env-kwargs: 'observation' must be key=value"),
        (["=1"], "key ''"),
        (["a=1", "a=2"], "'a' given twice"),
        (["a=b c"], "neither a Python literal nor a bare word"),
        (["1a=2"], "must be a Python identifier"),
    ],
)
def test_bad_items_are_one_line(items, words) -> None:
    with pytest.raises(ValueError) as err:
        parse_options(items, "--env-kwargs")
    assert words in str(err.value) and str(err.value).startswith("--env-kwargs") and "\n" not in str(err.value)
