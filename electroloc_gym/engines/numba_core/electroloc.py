"""ElectroLoc-v0's task: the ``localize`` task with its two optional variants, in one class.

* a sensor array and the stationary carriage (``sensor_layout=``, ``fixed_carriage=``,
  :class:`~electroloc_gym.engines.numba_core.array.ArrayLocalizeTask`);
* distractors in the true reading (``distractors=``,
  :class:`~electroloc_gym.engines.numba_core.distractor_task.LocalizeDistractorsTask`).

Each variant is a subclass of :class:`~electroloc_gym.engines.numba_core.localize_task.LocalizeTask` that runs the plain
task's methods unchanged when it is off, so with the defaults (the paper's one pair, a moving carriage,
no distractors) every draw, reading and update is the plain task's, bit for bit. The two compose by
Python's method order (distractors, then the array, then the plain task). An array together with
distractors is refused: the distractors' perturbation is computed for the paper's one pair.
"""

from __future__ import annotations

from dataclasses import dataclass

from electroloc_gym.contract.params import EnvParams, GainOptions, LocalizeOptions
from electroloc_gym.engines.numba_core.array import ArrayLocalizeTask, ArrayOptions
from electroloc_gym.engines.numba_core.distractor_task import DistractorOptions, LocalizeDistractorsTask

__all__ = ["ElectroLocTask", "ElectroLocOptions"]


@dataclass(frozen=True)
class ElectroLocOptions(DistractorOptions, ArrayOptions, GainOptions, LocalizeOptions):
    """ElectroLoc-v0's options: the tank's (``condition``, ``signal``, ``randomize_target``), the dynamic gain
    (``gain_levels``), the sensor array's (``sensor_layout``, ``fixed_carriage``) and ``distractors``.
    """


class ElectroLocTask(LocalizeDistractorsTask, ArrayLocalizeTask):
    """ElectroLoc-v0's task (module docstring).

    Raises:
        ValueError: ``distractors`` with a sensor array (one error naming both arguments), and each
            variant's own errors.
    """

    Options = ElectroLocOptions
    options: ElectroLocOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        if self.count and self.array:
            raise ValueError(
                "distractors: distractors are simulated for the paper's one electrode pair; use "
                "sensor_layout='single' with distractors, or distractors=0 with an array"
            )
