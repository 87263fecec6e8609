"""The agent protocol shared by the paper's controllers and learned policies, and the controllers' common base.

Every agent the benchmark runs answers SB3's call (``PolicyPredictor``)::

    action, state = agent.predict(observation, state=None, episode_start=None, deterministic=True)

plus ``agent.reset(env)``, called at the start of each trial *after* ``env.reset(...)``, which binds
the agent to the env. What the benchmark and the rollout hand ``reset`` is the env's *agent view*
(:func:`electroloc_gym.envs.agent_view.agent_view`): the documented agent accessors — the belief, the
sensor model, the carriage, the predicted readings — and no route to the true target. A controller given
a plain env binds to that env's agent view itself, so it reads the same accessors either way. Actions
are the env's continuous action, ``(dx, dy) ∈ [−1, 1]²`` = move / 10 mm (paper §4.1.3: at most 10 mm per
axis).

Attributes and optional hooks the benchmark runner understands:

* ``env_kwargs: dict`` — extra keyword arguments for ``gym.make("ElectroLoc-v0", ...)`` for this
  agent (``{}`` for the probabilistic baselines; a learned policy records its observation mode etc.).
* ``seed(seed)`` (optional) — re-seed the agent's own generator; the runner calls it before every
  trial with a seed derived from (condition, trial) so results do not depend on the worker count.
* ``done: bool`` and ``estimate_mm`` (optional) — an agent that ends a trial itself (zero-crossing)
  sets ``done = True`` in ``predict`` and reports its own target estimate ``(x, y)`` in mm (or
  ``None`` when it gave up: a failure). The runner then stops without stepping the env.
* ``adapt_condition(condition) -> Condition`` (optional) — the workspace layout the agent is
  evaluated in (zero-crossing: the paper's Table-1 layout, §6.4).
* ``table_layout: str`` (optional) — ``"table4"`` (default) or ``"table1"``: which of the paper's tables
  the agent's results belong to.
* ``cost_rank: int`` (optional) — how long the agent's trials take, by rank (0 the quickest; default 2, as
  a learned policy): the benchmark runs the highest ranks first, so the worker pool's tail is short.
* ``sensor_layouts: tuple[str, ...] | None`` (optional) — the named sensor layouts
  (``electroloc_gym.world.sensor_array.LAYOUT_NAMES``) the agent can run on; None (default): every one. The
  benchmark refuses a run on another layout before it writes anything, and a controller's ``reset``
  refuses an env of another layout (one ValueError): the same rule, :func:`layout_problem`.
* ``memory_bytes(n_particles) -> int`` and ``decision_seconds(n_particles) -> float`` (optional) — the
  agent's estimate of one decision's peak memory and time with a belief of ``n_particles``; the
  benchmark refuses a run that cannot fit in memory and warns before one whose decisions are slow.

:class:`BaselineAgent` is the controllers' common plumbing; every controller module imports this
module and nothing above it (the registry, :mod:`electroloc_gym.baselines.agent`, imports the
controllers). Learned policies follow the same protocol; the benchmark's agent registry
(:mod:`electroloc_gym.bench.agents`) loads them — the controllers never import the training package.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.envs.agent_view import AgentView, agent_view
from electroloc_gym.protocol import MAX_STEP_MM  # the largest move per axis per step, mm (paper §4.1.3)

__all__ = [
    "Agent",
    "BaselineAgent",
    "layout_problem",
    "require_target_belief",
    "sample_options_mm",
    "move_bounds_mm",
    "sample_belief",
    "MAX_STEP_MM",
]


@runtime_checkable
class Agent(Protocol):
    """What the benchmark runner calls. Learned policies (``electroloc_gym.policy.load``) implement the same."""

    env_kwargs: dict[str, Any]

    def reset(self, env: Any) -> None:
        """Bind to ``env`` at the start of a trial (after ``env.reset``): the env's agent view."""
        ...

    def predict(
        self,
        observation: NDArray[np.floating[Any]],
        state: Any = None,
        episode_start: NDArray[Any] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[Any], Any]:
        """The next action (2,) in [−1, 1]² and the recurrent state (``None`` for stateless agents)."""
        ...


class BaselineAgent:
    """Common plumbing of the paper's controllers: binding, seeding, episode flags.

    Args:
        seed: seed or generator of the agent's own randomness (never the global ``np.random``).
    """

    #: Registry name.
    name = "baseline"
    #: Which paper table the agent's results belong to.
    table_layout = "table4"
    #: How long a trial takes, by rank (0 the quickest): the benchmark runs the highest ranks first.
    cost_rank = 2
    #: The named sensor layouts the agent runs on (None: every one).
    sensor_layouts: tuple[str, ...] | None = None

    def __init__(self, seed: int | np.random.Generator | None = None) -> None:
        self.env_kwargs: dict[str, Any] = {}
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.done = False
        self.estimate_mm: tuple[float, float] | None = None
        #: Dynamic gain: the gain level the agent chose for the next reading (None: the preset gain).
        self.gain_level: int | None = None
        self._env: Any = None

    def seed(self, seed: int | None) -> None:
        """Re-seed the agent's generator (the runner calls this before each trial)."""
        self.rng = np.random.default_rng(seed)

    def reset(self, env: Any) -> None:
        """Bind to ``env``'s agent view (``env`` is one already in the benchmark) at the start of a trial.

        Raises:
            ValueError: the env's sensor layout is not one of :attr:`sensor_layouts` (:func:`layout_problem`).
        """
        view = agent_view(env)
        why = layout_problem(self, getattr(view, "sensor_layout", None))
        if why is not None:
            make = " or ".join(f"sensor_layout={n!r}" for n in self.sensor_layouts or ())
            raise ValueError(f"{self.name} cannot run on this env's sensor layout: {why} (make the env with {make})")
        self._env = view
        self.done = False
        self.estimate_mm = None

    @property
    def env(self) -> AgentView:
        """The bound env's agent view (:func:`electroloc_gym.envs.agent_view.agent_view`)."""
        if self._env is None:
            raise RuntimeError(f"{type(self).__name__}.reset(env) must be called before predict()")
        return self._env

    def predict(
        self,
        observation: NDArray[np.floating[Any]],
        state: Any = None,
        episode_start: NDArray[Any] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """SB3-style call; subclasses implement :meth:`choose_move_mm` (and may set :attr:`gain_level`).

        With dynamic gain (the env's ``gain_levels``) the action's third entry selects the gain: the
        agent's :attr:`gain_level`, or the preset gain's level (the factor nearest to 1).
        """
        return self.action_of(self.choose_move_mm()), state

    def action_of(self, move_mm: Any) -> NDArray[np.float32]:
        """The env action of a carriage move (dx, dy), mm, with the gain entry under dynamic gain."""
        action = (np.asarray(move_mm, dtype=np.float64) / MAX_STEP_MM).clip(-1.0, 1.0)
        if getattr(self.env, "gain_levels", None) is not None:
            level = self.env.preset_gain_level if self.gain_level is None else self.gain_level
            action = np.append(action, self.env.gain_action(level))
        return action.astype(np.float32)

    def choose_move_mm(self) -> NDArray[np.float64]:
        """The carriage move (dx, dy) in mm for the next step."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def layout_problem(agent: Any, sensor_layout: Any) -> str | None:
    """Why ``agent`` cannot run on a sensor layout (None: it can): its ``sensor_layouts`` (None or absent:
    every layout) lacks the layout's name.

    Args:
        agent: any agent (a plug-in's ``sensor_layouts`` is read the same way).
        sensor_layout: a layout name, an env's ``SensorLayout`` (its ``name``), or None (the paper's single pair).
    """
    supported = getattr(agent, "sensor_layouts", None)
    layout = getattr(sensor_layout, "name", sensor_layout) or "single"
    if supported is None or layout in supported:
        return None
    return f"it runs on the sensor layout(s) {list(supported)} only, not {layout!r}"


def require_target_belief(env: Any, agent_name: str) -> None:
    """Raise one ValueError unless ``env``'s belief is over the target's position (hypotheses that do not
    move with the robot): ElectroLoc-v0 and ElectroLocUnknownTarget-v0, not ElectroLocGlobal-v0.
    """
    if env.belief_frame == "robot":
        raise ValueError(
            f"{agent_name} needs a belief over the target's position (ElectroLoc-v0, "
            "ElectroLocUnknownTarget-v0); this env's belief is over the robot's own position "
            "(ElectroLocGlobal-v0): use min-var or lookahead there"
        )


def move_bounds_mm(env: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lo, hi) moves per axis, mm, within ±10 mm that keep the carriage in the allowed box.

    Uses the env's ``move_bounds_mm`` accessor when it has one (the global-localisation env, where the
    robot cannot know where the walls are, answers ±10 mm), else derives it from ``position_mm`` and
    ``allowed_box_mm``. 0 is always inside. ``env``: an agent view, an env or its core.
    """
    core = agent_view(env)
    if hasattr(core, "move_bounds_mm"):
        lo, hi = core.move_bounds_mm
        return np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    p = np.asarray(core.position_mm, dtype=np.float64)
    low, high = core.allowed_box_mm
    lo = np.minimum(np.maximum(-MAX_STEP_MM, np.asarray(low, dtype=np.float64) - p), 0.0)
    hi = np.maximum(np.minimum(MAX_STEP_MM, np.asarray(high, dtype=np.float64) - p), 0.0)
    return lo, hi


def sample_options_mm(
    rng: np.random.Generator, lo_mm: ArrayLike, hi_mm: ArrayLike, n_options: int = 16
) -> NDArray[np.float64]:
    """The paper's control options (§4.1.3): stay, plus ``n_options − 1`` uniform moves in ±10 mm.

    The random moves are drawn uniformly from the move bounds ``[lo_mm, hi_mm]`` per axis (the
    ±10 mm square clipped to the allowed box, :func:`move_bounds_mm`), so no option is wasted on a
    wall (the robot "was permitted to move anywhere within" the box, §5.4).

    Returns:
        (n_options, 2) moves in mm; row 0 is the stay option (0, 0).
    """
    if n_options < 1:
        raise ValueError(f"n_options must be ≥ 1, got {n_options!r}")
    lo = np.asarray(lo_mm, dtype=np.float64)
    hi = np.asarray(hi_mm, dtype=np.float64)
    moves = np.zeros((n_options, 2))
    moves[1:] = lo + (hi - lo) * rng.random((n_options - 1, 2))
    return moves


def sample_belief(
    belief: Any, n: int | None, rng: np.random.Generator, keep_weights: bool = False
) -> tuple[NDArray[Any], NDArray[np.float64] | None]:
    """A planner's hypotheses: the belief's particles, or ``n`` of them drawn from its weights.

    Args:
        belief: the env's ``belief`` accessor (``particles`` (M, d), ``weights`` (M,)).
        n: how many hypotheses (None or ≥ M: the whole belief when it is equally weighted).
        rng: the agent's generator.
        keep_weights: with unequal weights and ``n`` None or ≥ M, return the whole belief with its weights
            (the caller weighs them) instead of ``n`` draws.

    Returns:
        (hypotheses (S, d), their weights or None when they are equally weighted). With equal weights a
        subset is drawn without replacement; with unequal weights ``n`` are drawn with replacement by weight
        (then equally weighted), both kept in the belief's order.
    """
    x = np.asarray(belief.particles)
    w = np.asarray(belief.weights, dtype=np.float64)
    m = x.shape[0]
    if np.all(w == w[0]):
        if n is None or n >= m:
            return x, None
        return x[np.sort(rng.choice(m, size=n, replace=False))], None
    if keep_weights and (n is None or n >= m):
        return x, w
    return x[np.sort(rng.choice(m, size=m if n is None else n, replace=True, p=w / w.sum()))], None
