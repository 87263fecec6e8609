"""The torch backend episode by episode in distribution: the benchmark's 400 trial seeds (8 conditions × 50,
seed 0, the paper's fixed target) run on both backends by uniform random moves, the paper's rnd-wlk (its
16 options drawn in the carriage's box: it reads the carriage's position from the info, the box from the
condition; each sub-env's agent on the trial's agent seed), the shipped ppo-belief and the paper's
min-var (one agent per sub-env on the trial's agent seed, reading its sub-env through
``TorchElectroLocVectorEnv.sub_env``: the belief, the carriage and the torch core's predicted readings).
min-var's numba side is the reference benchmark run's 400 trials (experiments/reference/bench), checked
to be the numba core's by rerunning trial 0 of every condition. The two backends draw different
streams, so the episodes differ one by one; the torch
backend's success rate must lie inside the numba core's 95 % Wilson interval and its mean readings (a
failure counts as the 35-reading cap) inside the numba core's 95 % t-interval. Fixed seeds: the check
is deterministic."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402, F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.bench import run  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.bench.records import read_trials  # noqa: E402
from electroloc_gym.protocol import MAX_OBSERVATIONS  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition  # noqa: E402

TRIALS = 50
REFERENCE = Path(__file__).resolve().parents[1] / "experiments" / "reference" / "bench" / "trials.jsonl"


class _CarriageView:
    """What rnd-wlk reads of its env — the carriage's position and its allowed box, mm — for one sub-env."""

    def __init__(self, half_mm: float) -> None:
        self.allowed_box_mm = (np.array([-half_mm, -half_mm]), np.array([half_mm, half_mm]))
        self.position_mm = np.zeros(2)
        self.unwrapped = self


def _rnd_wlk_policy(condition: str):
    """A batch policy of one rnd-wlk per sub-env (trial k's agent seed), fed the info's carriage positions."""
    from electroloc_gym.baselines.random_walk import RandomWalkAgent

    half = get_condition(condition).allowed_half_width_mm
    views = [_CarriageView(half) for _ in range(TRIALS)]
    agents = [RandomWalkAgent(seed=trial_seeds(0, condition, k)[1]) for k in range(TRIALS)]
    for agent, view in zip(agents, views):
        agent.reset(view)

    def act(positions: np.ndarray) -> np.ndarray:
        for view, p in zip(views, positions):
            view.position_mm = np.asarray(p, dtype=np.float64)
        return np.stack([agent.predict(None)[0] for agent in agents])

    return act


def _first_episodes(backend: str, condition: str, policy) -> tuple[np.ndarray, np.ndarray]:
    """(success, readings) of each sub-env's first episode, sub-env k on trial k's env seed; ``policy``: None
    (uniform random moves), "rnd-wlk", "min-var" (torch only) or a batch policy with ``predict``."""
    kw = {"backend": "torch", "device": "cpu"} if backend == "torch" else {}
    env = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=TRIALS,
        vectorization_mode="vector_entry_point",
        condition=condition,
        randomize_target=False,
        **kw,
    )
    obs, info = env.reset(seed=[trial_seeds(0, condition, k)[0] for k in range(TRIALS)])
    done, success, readings = np.zeros(TRIALS, bool), np.zeros(TRIALS, bool), np.zeros(TRIALS)
    rng = np.random.default_rng(7)
    host = (lambda x: x.cpu().numpy()) if backend == "torch" else np.asarray
    walk = _rnd_wlk_policy(condition) if policy == "rnd-wlk" else None
    planners = None
    if policy == "min-var":  # one agent per sub-env, reading it through the torch env's sub_env view
        planners = [make_agent("min-var", seed=trial_seeds(0, condition, k)[1]) for k in range(TRIALS)]
        for k, agent in enumerate(planners):
            agent.reset(env.unwrapped.sub_env(k))
    while not done.all():
        o = host(obs)
        if walk is not None:
            action = walk(host(info["position_mm"])).astype(np.float32)
        elif planners is not None:
            action = np.zeros((TRIALS, 2), dtype=np.float32)
            for k in np.flatnonzero(~done):  # a finished sub-env's agent is not asked again
                action[k] = planners[k].predict(None)[0]
        elif policy is not None:
            action = policy.predict(o)[0]
        else:
            action = rng.uniform(-1, 1, (TRIALS, 2)).astype(np.float32)
        obs, _, term, trunc, info = env.step(torch.as_tensor(action) if backend == "torch" else action)
        new = (host(term) | host(trunc)) & ~done
        success[new], readings[new] = host(info["success"])[new], host(info["n_observations"])[new]
        done |= new
    env.close()
    return success, np.where(success, readings, MAX_OBSERVATIONS)


@pytest.fixture(scope="module")
def ppo_belief():
    from electroloc_gym.bench.agents import cached_agent

    return cached_agent("ppo-belief")


def _assert_inside_numba_intervals(agent: str, success: dict, readings: dict) -> None:
    """The torch backend's success rate inside the numba core's 95 % Wilson interval, its mean readings
    inside the numba core's 95 % t-interval (over the same trial seeds)."""
    n = len(success["numba"])
    assert n == len(success["torch"]) == 8 * TRIALS
    ci = stats.binomtest(int(success["numba"].sum()), n).proportion_ci(0.95, method="wilson")
    assert ci.low <= success["torch"].mean() <= ci.high, (agent, success["torch"].mean(), ci)
    print(
        f"{agent}: successes {int(success['numba'].sum())} / {int(success['torch'].sum())}, mean readings "
        f"{readings['numba'].mean():.2f} / {readings['torch'].mean():.2f} (numba / torch)"
    )
    r = readings["numba"]
    half = stats.t.ppf(0.975, n - 1) * r.std(ddof=1) / np.sqrt(n)
    assert abs(readings["torch"].mean() - r.mean()) <= half, (agent, readings["torch"].mean(), r.mean(), half)


@pytest.mark.parametrize("agent", ["random", "rnd-wlk", "ppo-belief"])
def test_the_torch_backend_localises_as_the_numba_core_does(agent, request) -> None:
    policy = request.getfixturevalue("ppo_belief") if agent == "ppo-belief" else agent if agent == "rnd-wlk" else None
    runs = {b: [_first_episodes(b, c, policy) for c in PRESET_NAMES] for b in ("numba", "torch")}
    success = {b: np.concatenate([s for s, _ in r]) for b, r in runs.items()}
    readings = {b: np.concatenate([x for _, x in r]) for b, r in runs.items()}
    _assert_inside_numba_intervals(agent, success, readings)


def _reference_min_var() -> dict[tuple[str, int], dict]:
    rows = [r for r in read_trials(REFERENCE) if r["agent"] == "min-var"]
    return {(r["condition"], int(r["trial"])): r for r in rows}


def test_the_reference_min_var_trials_are_the_numba_cores(tmp_path) -> None:
    """Trial 0 of every condition, rerun now on the numba core, gives the reference run's record."""
    reference = _reference_min_var()
    result = run(agents=["min-var"], conditions="all", trials=1, seed=0, out=tmp_path / "bench")
    rerun = read_trials(result.out / "trials.jsonl")
    assert len(rerun) == len(PRESET_NAMES)
    for r in rerun:
        ref = reference[(r["condition"], 0)]
        assert (r["seed"], r["agent_seed"]) == (ref["seed"], ref["agent_seed"])
        keys = ("success", "readings", "error_mm")
        assert [r[k] for k in keys] == [ref[k] for k in keys], r["condition"]


@pytest.mark.long  # about a minute and a half: min-var's 4,600 decisions
def test_min_var_on_the_torch_backend_localises_as_on_the_numba_core() -> None:
    reference = _reference_min_var()
    numba = [reference[(c, k)] for c in PRESET_NAMES for k in range(TRIALS)]
    assert all(r["seed"] == trial_seeds(0, r["condition"], r["trial"])[0] for r in numba)
    ok = np.array([bool(r["success"]) for r in numba])
    success = {"numba": ok}
    readings = {"numba": np.where(ok, [r["readings"] for r in numba], MAX_OBSERVATIONS)}
    runs = [_first_episodes("torch", c, "min-var") for c in PRESET_NAMES]
    success["torch"] = np.concatenate([s for s, _ in runs])
    readings["torch"] = np.concatenate([x for _, x in runs])
    _assert_inside_numba_intervals("min-var", success, readings)
