"""own_task: frugal localisation, a task of your own in one file (``FrugalLoc-v0``, ``--env own_task:frugal``).

The robot of the paper localises a target sphere by moving its sensing carriage; every reading costs one
step. Here the carriage's travel costs energy too: the motors of the x–y stage draw power for every mm
moved, and a battery holds a finite amount. A frugal agent trades readings for travel. Nothing of this file
is in the package: it uses the public API (:mod:`electroloc_gym.tasks`) only.

What each declaration is for:

* ``FrugalOptions`` — the env's own keyword arguments (beside the tank's: condition, signal,
  randomize_target, and the shared ones: n_particles, max_observations, …): ``travel_cost_per_mm`` (the
  reward's price of a mm of travel, in readings) and ``travel_budget_mm`` (the battery: the episode is
  truncated once the carriage has travelled that far; None: no budget). Each has a unit, a range and a doc;
  ``gym.make("FrugalLoc-v0", travel_cost_per_mm=-1)`` is one ValueError naming the argument and its range.
* ``FrugalState`` — the per-env arrays the task keeps: ``travel_mm`` (the episode's travel so far) and
  ``move_mm`` (the last step's), allocated, reset to 0 and gathered per env by the engine.
* ``FrugalTask`` — the localise task (``LocalizeTask``: the tank, the sensor, the belief) with three
  methods changed: ``move`` adds the carriage's actual travel (after the walls), ``rewards`` charges it,
  ``flags`` truncates on the budget; ``task_info`` reports ``travel_mm``, ``cost`` and ``budget_spent``.
* ``FRUGAL_METRICS`` — what the benchmark, the datasets and training report: the record fields (the final
  info's ``travel_mm``, ``cost``, ``budget_spent``; checked on ``--resume``), their statistics per condition
  (median travel and its IQR, mean cost), the table's columns, and the score that ranks agents and picks
  training's best checkpoint: ``cost`` = readings (a failure counted as the cap) + ``travel_cost_per_mm`` ×
  travel, lower better.
* ``ENTRY`` — the env-table entry, registered when this module is imported (``register_env``): its id, task
  name, sensor models, defaults and its ``electroloc bench --env frugal`` row; no env class to write.

Run it: ``python examples/own_task.py`` (a few steps); ``electroloc bench --env own_task:frugal --trials 2``
with ``examples/`` on PYTHONPATH; ``gym.make("own_task:FrugalLoc-v0")`` from any script.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from electroloc_gym.tasks import (
    LOCALIZATION_METRICS,
    BenchEnv,
    Column,
    CurvePanel,
    EnvEntry,
    LocalizeOptions,
    LocalizeTask,
    Optional,
    Real,
    RecordField,
    Score,
    State,
    Table,
    TaskMetrics,
    TaskState,
    option,
    register_env,
    state_array,
)

ENV_ID = "FrugalLoc-v0"
#: The largest budget and travel a record may hold, mm (far beyond any episode's reach).
MAX_TRAVEL_MM = 1.0e6


@dataclass(frozen=True)
class FrugalOptions(LocalizeOptions):
    """FrugalLoc-v0's own options (the tank's are inherited)."""

    travel_cost_per_mm: float = option(
        0.05,
        doc="the reward's price of the carriage's travel (0.05: a 10 mm move costs half a reading)",
        check=Real(0.0, 10.0, inclusive=True),
        unit="reading/mm",
    )
    travel_budget_mm: float | None = option(
        None,
        doc="the battery: the episode is truncated once the carriage travelled this far (None: no budget)",
        check=Optional(Real(0.0, MAX_TRAVEL_MM)),
        unit="mm",
    )


@dataclass
class FrugalState(TaskState):
    """FrugalLoc-v0's per-env arrays: the episode's travel and the last step's, mm."""

    travel_mm: np.ndarray = state_array(np.float64)
    move_mm: np.ndarray = state_array(np.float64)


class FrugalTask(LocalizeTask):
    """Localise the target sphere; every mm the carriage travels costs ``travel_cost_per_mm`` readings."""

    Options = FrugalOptions
    State = FrugalState
    info_keys = ("travel_mm", "cost", "budget_spent")

    def __init__(self, params: Any) -> None:
        super().__init__(params)
        self.frugal: FrugalOptions = params.options_as(FrugalOptions)

    def move(self, state: State, ids: Any, moves_mm: np.ndarray) -> None:
        """The carriage moves (truncated at the walls, the shared rule); its actual travel is added up."""
        before = state.position_mm[ids].copy()
        super().move(state, ids, moves_mm)
        step = np.hypot(*(state.position_mm[ids] - before).T)
        own = FrugalState.of(state)
        own.move_mm[ids] = step
        own.travel_mm[ids] += step

    def rewards(self, state: State) -> np.ndarray:
        """−1 per reading, minus the step's travel times ``travel_cost_per_mm``."""
        return super().rewards(state) - self.frugal.travel_cost_per_mm * FrugalState.of(state).move_mm

    def _spent(self, state: State, sel: Any = slice(None)) -> np.ndarray:
        budget = self.frugal.travel_budget_mm
        travel = FrugalState.of(state).travel_mm[sel]
        return np.zeros(travel.shape, dtype=bool) if budget is None else travel >= budget

    def flags(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """The shared rule (success, the cap of readings), and truncated once the travel budget is spent."""
        terminated, truncated = super().flags(state)
        return terminated, truncated | (~terminated & self._spent(state))

    def task_info(self, state: State, sel: Any) -> dict[str, np.ndarray]:
        """``travel_mm``; ``cost``: readings (the cap on failure) + price × travel; ``budget_spent``."""
        travel = FrugalState.of(state).travel_mm[sel].copy()
        spread = state.spread_mm()[sel]
        readings = np.where(
            spread <= self.params.success_spread_mm, state.n_observations[sel], self.params.max_observations
        )
        cost = readings + self.frugal.travel_cost_per_mm * travel
        return {"travel_mm": travel, "cost": cost.astype(np.float64), "budget_spent": self._spent(state, sel)}


# ---- what the benchmark, the datasets and training report --------------------------------------------------


def frugal_statistics(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Over a group of trial records: the travel's median and IQR (mm), the mean cost, the budget stops."""
    results = [r["shape"] for r in records if r.get("shape") and "travel_mm" in r["shape"]]
    if not results:
        return {}
    travel = np.asarray([float(s["travel_mm"]) for s in results])
    q25, q50, q75 = (float(q) for q in np.quantile(travel, [0.25, 0.5, 0.75]))
    return {
        "frugal_trials": len(results),
        "travel_median_mm": q50,
        "travel_q25_mm": q25,
        "travel_q75_mm": q75,
        "cost_mean": float(np.mean([float(s["cost"]) for s in results])),
        "budget_stops": sum(bool(s["budget_spent"]) for s in results),
    }


def _outcome(info: Mapping[str, Any]) -> str:
    if bool(info["success"]):
        return f"success after {int(info['n_observations'])} readings and {float(info['travel_mm']):.0f} mm"
    return "failure (travel budget spent)" if bool(info["budget_spent"]) else "failure (observation cap)"


FRUGAL_METRICS = TaskMetrics(
    record=(
        RecordField("travel_mm", "the carriage's travel over the episode", "mm", low=0.0, high=MAX_TRAVEL_MM),
        RecordField("cost", "readings (the cap on failure) + price × travel", "readings", low=0.0, high=1e9),
        RecordField("budget_spent", "the episode was truncated by the travel budget", kind="bool"),
    ),
    statistics=frugal_statistics,
    statistic_keys=("frugal_trials", "travel_median_mm", "travel_q25_mm", "travel_q75_mm", "cost_mean", "budget_stops"),
    columns=(
        Column("frugal_trials", "Trials", format="{frugal_trials}"),
        Column("travel_median_mm", "Travel median (mm)", better="lower"),
        Column(
            "travel_median_mm",
            "Travel IQR (mm)",
            format="{travel_q25_mm:.0f}–{travel_q75_mm:.0f}",
            interval=("travel_q25_mm", "travel_q75_mm"),
        ),
        Column("cost_mean", "Mean cost (readings)", better="lower", format="{cost_mean:.2f}"),
        Column("budget_stops", "Budget stops", format="{budget_stops}"),
    ),
    table=Table(
        title="Travel (frugal localisation)",
        text=(
            "The carriage's travel per trial ({trials} trials per condition and agent): its median and interquartile "
            "range, and the mean cost, readings (a failure counted as the cap of {max_observations}) plus the "
            "travel's price."
        ),
        count="frugal_trials",
        pooled=" (pooled)",
    ),
    score=Score("cost", "lower", "readings plus travel cost", "readings", name="frugal_cost"),
    rate=LOCALIZATION_METRICS.rate,
    outcome=_outcome,
    curves=(
        LOCALIZATION_METRICS.curves[0],
        CurvePanel("mean_cost", "mean cost (readings + price × travel)"),
        CurvePanel("median_travel_mm", "median travel (mm)"),
    ),
    eval_columns={
        "mean_cost": lambda infos: float(np.mean([float(i["cost"]) for i in infos])),
        "median_travel_mm": lambda infos: float(np.median([float(i["travel_mm"]) for i in infos])),
    },
    dataset_info=("travel_mm",),
)
FrugalTask.metrics = FRUGAL_METRICS

ENTRY = register_env(
    EnvEntry(
        env_id=ENV_ID,
        task="frugal",
        task_class=FrugalTask,
        sensor_models=("calibrated", "analytic"),
        bench=(BenchEnv("frugal", agents=("rnd-wlk", "min-var"), summary="localisation with a price on travel"),),
        summary="localise a target sphere; the carriage's travel costs energy",
    )
)


if __name__ == "__main__":
    import gymnasium as gym

    env = gym.make(ENV_ID, n_particles=500, travel_budget_mm=60.0)
    obs, info = env.reset(seed=0)
    env.action_space.seed(0)
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += float(reward)
        done = terminated or truncated
    print(f"{ENV_ID}: {FRUGAL_METRICS.outcome(info)}; travel {info['travel_mm']:.1f} mm, return {total:.2f}")
    env.close()
