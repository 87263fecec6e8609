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
    """The env ElectroLoc-v0: what it simulates, its spaces, reward, episode end, info and arguments.

    ## Description

    The robot of Solberg, Lynch & MacIver (IJRR 2008, "Active Electrolocation for Underwater Target
    Localization"). A carriage carrying two field emitters and two voltage sensors (50 mm apart)
    moves in a horizontal plane over a water tank. A sphere below distorts the emitted field; the
    robot reads the amplified, noisy, saturating difference of the two sensor voltages. A particle
    filter (2500 particles, paper §4.1) holds the belief of where the target is. The agent moves the
    carriage until the belief is tight: √trace Σ ≤ 10 mm.

    ## Action Space

    ``action_type="continuous"`` (default): ``Box(-1, 1, (2,), float32)``, scaled to a move of at most
    10 mm per axis; finite values outside [−1, 1] are clipped. The carriage is kept inside the allowed
    box (the move is truncated at the walls). ``action_type="discrete"``: ``Discrete(9)``, stay or one of
    the 8 moves of ±10 mm / 0 per axis (index = 3·(dx+1) + (dy+1)).

    ## Observation Space

    ``observation="belief"`` (default): ``Box(-1, 1, (81,), float32)``: the carriage position, the last
    reading, the belief's mean, spread, correlation and 8×8 egocentric histogram, the observations used
    and a condition descriptor; the layout table is :mod:`electroloc_gym.contract.observation`'s (also in
    docs/environments.md).

    ``observation="raw"``: ``Box(-1, 1, (3,), float32)`` = [x/H, y/H, Φ/10 V] (no belief).

    With a sensor array of K pairs (``sensor_layout``, below) entry 2–3 hold pair 0's reading and K − 1 entries
    follow the 81: Φ_k / 10 V of pairs 1..K−1 (``Box(-1, 1, (80 + K,))``); ``"raw"``: [x/H, y/H, Φ_0/10 V, …,
    Φ_{K−1}/10 V].

    ## Rewards

    −1 per step (every new reading). Minimising the return minimises the observations used.

    ## Starting State

    The target sits at the condition's ``target_xy_mm`` (tank centre for the paper's presets; uniform
    in the start box with ``randomize_target=True``). The carriage starts uniformly in the start box
    (±40 mm for 12.7 mm spheres, ±55 mm for 38.1 mm). The particles are uniform over the allowed box
    (±50 / ±60 mm). reset() takes and fuses the first reading (observation count 1).

    ## Episode End

    * Termination: the belief's spread √trace Σ ≤ ``success_spread_mm`` (10 mm): success.
    * Truncation: ``max_observations`` readings (35, paper §5.4) fused without success: failure.

    The observation cap is enforced by the env itself rather than a ``TimeLimit`` wrapper, because it
    counts observations (the first one is taken by reset) and is part of the observation (index 11);
    a wrapper the env cannot see would make that feature lie when a user changes the cap. Stepping
    after the episode ended (terminated or truncated) raises: call reset.

    ## Info

    ``position_mm``, ``estimate_mm`` (tuples of float, mm), ``error_mm`` (estimate − true target),
    ``spread_mm``, ``reading_V``, ``n_observations``, ``success``, ``condition`` (name). ``error_mm``
    uses the ground truth: it is for evaluation, agents must not act on it.
    With a sensor array: ``reading_V`` is pair 0's, ``pair_readings_V`` (K,) every pair's (V), ``n_readings``
    = K × ``n_observations`` (the cap counts snapshots of K readings).

    ## Accessors (read-only, on ``env.unwrapped``)

    ``belief`` (:class:`~electroloc_gym.views.belief.BeliefView` over the target position: ``particles``,
    ``weights``, ``mean()``, ``covariance()``, ``spread()``), ``sensor_model``, ``condition``,
    ``position_mm`` (carriage), ``allowed_box_mm``, ``move_bounds_mm``, ``n_observations``,
    ``last_reading_V``, ``path_mm``, ``target_mm`` (ground truth, for evaluation and rendering only);
    ``predicted_reading_model(particles_mm, moves_mm)`` → (mean_V, std_V) of the reading each target
    hypothesis predicts after a commanded move (offsets = particle − clip(carriage + move)), and
    ``predicted_particles_mm`` (the target does not move: the particles unchanged). The same calls
    exist on ``ElectroLocGlobal-v0`` (the same core, :mod:`electroloc_gym.engines.numba_core`). With a sensor array of
    K ≥ 2
    pairs ``predicted_reading_model`` returns (…, K) means and stds (the pair axis last), ``sensor_model`` the
    K-pair model, ``last_readings_V`` every pair's last reading, ``sensor_layout`` the pairs, and
    ``fixed_carriage`` says whether moves are ignored (``move_bounds_mm`` is then (0, 0)).

    ## Arguments

    ```python
    gym.make("ElectroLoc-v0", condition="fresh-steel-12.7", observation="belief",
             sensor_model="calibrated", n_particles=2500, max_observations=35,
             success_spread_mm=10.0, signal=<get_condition's default>, action_type="continuous",
             randomize_target=False, calibration_seed=None, calibration=DEFAULT_CALIBRATION,
             max_episode_steps=None, render_mode=None)
    ```

    Every argument is a field of :class:`electroloc_gym.contract.params.EnvParams` (units and ranges
    there); any other argument, or a value out of range, is a ValueError naming it.

    * ``condition``: a preset name (``electroloc_gym.PRESET_NAMES``), a ``Condition``, or ``"random"`` to
      draw one of the eight presets per episode.
    * ``sensor_model``: the agent's (and the filter's) sensor model, ``"analytic"`` or ``"calibrated"``
      (the paper's 4 mm grid of 10 readings, §5.3, drawn per episode from ``calibration_seed`` or,
      if None, from the env's seeded generator; ``calibration`` changes the protocol).
    * ``signal``: the presets' signal scale (:func:`electroloc_gym.world.conditions.get_condition`:
      ``"fitted"`` to the hardware's detection distances, Table 3, ``"paper"``: the paper's equations,
      ``"coverage"``, or a number); ignored for a ``Condition``.
    * ``distractors``: objects that are not the target (:mod:`electroloc_gym.engines.numba_core.distractor_task`): a
    count D
      (0–8) drawn per episode clear of the target, a list of counts (one drawn per episode), or an explicit
      layout; they add to the true reading only (the agent's model knows the target alone), and the info
      then has ``distractors_mm`` (their centres, for evaluation and rendering only). 0 (default): none.

    * ``sensor_layout``: the carriage's sensing pairs (§7, :mod:`electroloc_gym.engines.numba_core.array`): a name of
      ``electroloc_gym.world.sensor_array.LAYOUT_NAMES``, a ``SensorLayout``, or (K, 2, 2) electrode offsets in mm;
      ``"single"`` (default) is the paper's pair. Each step takes K readings, fused one filter update per reading.
    * ``fixed_carriage``: the carriage never moves (the stationary array); actions are accepted and ignored.

    ## Version History

    * v0: initial version.

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
