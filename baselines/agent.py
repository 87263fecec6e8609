"""The agent protocol shared by the paper's controllers and learned policies, and the agent registry.

Every agent the benchmark runs answers SB3's call (``PolicyPredictor``)::

    action, state = agent.predict(observation, state=None, episode_start=None, deterministic=True)

plus ``agent.reset(env)``, called at the start of each trial *after* ``env.reset(...)``, which binds
the agent to the env (agents that need the belief or the sensor model read ``env.unwrapped.belief``
and ``env.unwrapped.sensor_model``; none ever reads the true target). Actions are the env's
continuous action, ``(dx, dy) ∈ [−1, 1]²`` = move / 10 mm (paper §4.1.3: at most 10 mm per axis).

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
* ``layout: str`` (optional) — ``"table4"`` (default) or ``"table1"``: which of the paper's tables
  the agent's results belong to.

:func:`make_agent` builds one of the paper's controllers from a name (``rnd-wlk``, ``min-var``,
``zero-crossing``), optionally with keyword options in brackets (``min-var[n_voters=2500]``). Learned
policies follow the same protocol; the benchmark's agent registry (:mod:`electroloc_gym.bench.agents`)
loads them — the controllers never import the training package.
"""

from __future__ import annotations

import ast
import re
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Agent",
    "BaselineAgent",
    "AGENT_REGISTRY",
    "EXTRA_AGENTS",
    "make_agent",
    "parse_agent_spec",
    "sample_options_mm",
    "move_bounds_mm",
    "MAX_STEP_MM",
]

#: Largest move per axis per step, mm (paper §4.1.3; equals the env's action scale).
MAX_STEP_MM = 10.0


@runtime_checkable
class Agent(Protocol):
    """What the benchmark runner calls. Learned policies (``electroloc_gym.train.policy``) implement the same."""

    env_kwargs: dict[str, Any]

    def reset(self, env: Any) -> None:
        """Bind to ``env`` at the start of a trial (after ``env.reset``)."""
        ...

    def predict(self, observation: NDArray, state: Any = None, episode_start: NDArray | None = None,
                deterministic: bool = True) -> tuple[NDArray, Any]:
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
    layout = "table4"

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
        """Bind to ``env`` (its ``unwrapped`` core) at the start of a trial."""
        self._env = env.unwrapped
        self.done = False
        self.estimate_mm = None

    @property
    def env(self) -> Any:
        """The bound env core (``env.unwrapped``)."""
        if self._env is None:
            raise RuntimeError(f"{type(self).__name__}.reset(env) must be called before predict()")
        return self._env

    def predict(self, observation: NDArray, state: Any = None, episode_start: NDArray | None = None,
                deterministic: bool = True) -> tuple[NDArray[np.float32], Any]:
        """SB3-style call; subclasses implement :meth:`choose_move_mm` (and may set :attr:`gain_level`).

        With dynamic gain (the env's ``gain_levels``) the action's third entry selects the gain: the
        agent's :attr:`gain_level`, or the preset gain's level (the factor nearest to 1).
        """
        return self.action_of(self.choose_move_mm()), state

    def action_of(self, move_mm: Any) -> NDArray[np.float32]:
        """The env action of a carriage move (dx, dy), mm, with the gain entry under dynamic gain."""
        action = np.clip(np.asarray(move_mm, dtype=np.float64) / MAX_STEP_MM, -1.0, 1.0)
        if getattr(self.env, "gain_levels", None) is not None:
            level = self.env.preset_gain_level if self.gain_level is None else self.gain_level
            action = np.append(action, self.env.gain_action(level))
        return action.astype(np.float32)

    def choose_move_mm(self) -> NDArray[np.float64]:
        """The carriage move (dx, dy) in mm for the next step."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def move_bounds_mm(env: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lo, hi) moves per axis, mm, within ±10 mm that keep the carriage in the allowed box.

    Uses the env's ``move_bounds_mm`` accessor when it has one (the global-localisation env, where the
    robot cannot know where the walls are, answers ±10 mm), else derives it from ``position_mm`` and
    ``allowed_box_mm``. 0 is always inside.
    """
    core = env.unwrapped if hasattr(env, "unwrapped") else env
    if hasattr(core, "move_bounds_mm"):
        lo, hi = core.move_bounds_mm
        return np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    p = np.asarray(core.position_mm, dtype=np.float64)
    low, high = core.allowed_box_mm
    lo = np.minimum(np.maximum(-MAX_STEP_MM, np.asarray(low, dtype=np.float64) - p), 0.0)
    hi = np.maximum(np.minimum(MAX_STEP_MM, np.asarray(high, dtype=np.float64) - p), 0.0)
    return lo, hi


def sample_options_mm(rng: np.random.Generator, lo_mm: NDArray, hi_mm: NDArray,
                      n_options: int = 16) -> NDArray[np.float64]:
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


# ---------------------------------------------------------------------------------------------
# Registry
# ---------------------------------------------------------------------------------------------
def _registry() -> dict[str, type]:
    from electroloc_gym.baselines.eedi import EEDIAgent
    from electroloc_gym.baselines.infotaxis import InfotaxisAgent
    from electroloc_gym.baselines.lookahead import LookaheadAgent
    from electroloc_gym.baselines.min_variance import MinVarianceAgent
    from electroloc_gym.baselines.random_walk import RandomWalkAgent
    from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent

    return {"rnd-wlk": RandomWalkAgent, "min-var": MinVarianceAgent, "zero-crossing": ZeroCrossingAgent,
            "lookahead": LookaheadAgent, "infotaxis": InfotaxisAgent, "eedi": EEDIAgent}


#: Names of the built-in agents (classes resolved lazily by :func:`make_agent`).
AGENT_REGISTRY: tuple[str, ...] = ("rnd-wlk", "min-var", "zero-crossing")
#: Agents beyond the paper's controllers, built by :func:`make_agent` but not in default benchmark runs.
EXTRA_AGENTS: tuple[str, ...] = ("lookahead", "infotaxis", "eedi")

_SPEC_RE = re.compile(r"^(?P<name>[A-Za-z0-9_\-]+)(\[(?P<opts>.*)\])?$")


def parse_agent_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """Split ``"min-var[n_voters=2500,n_options=16]"`` into ``("min-var", {"n_voters": 2500, ...})``.

    Raises:
        ValueError: malformed spec or option value.
    """
    m = _SPEC_RE.match(spec.strip())
    if m is None:
        raise ValueError(f"agent spec {spec!r} is malformed; expected NAME or NAME[key=value,...] "
                         f"with NAME in {list(AGENT_REGISTRY)}")
    kwargs: dict[str, Any] = {}
    opts = m.group("opts")
    if opts:
        for item in opts.split(","):
            if "=" not in item:
                raise ValueError(f"agent option {item!r} in {spec!r} must be key=value")
            key, val = (s.strip() for s in item.split("=", 1))
            try:
                kwargs[key] = ast.literal_eval(val)
            except (ValueError, SyntaxError):
                kwargs[key] = val
    return m.group("name"), kwargs


def make_agent(spec: str, seed: int | np.random.Generator | None = None) -> BaselineAgent:
    """Build one of the paper's controllers from its name, optionally with options.

    Args:
        spec: ``"rnd-wlk"``, ``"min-var"``, ``"zero-crossing"`` or e.g. ``"min-var[n_voters=2500]"``.
        seed: seed of the agent's own generator.

    Raises:
        ValueError: an unknown name or bad options (the message lists the names).
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"agent must be a non-empty string, got {spec!r}")
    name, kwargs = parse_agent_spec(spec)
    registry = _registry()
    if name not in registry:
        raise ValueError(f"unknown agent {name!r}; choose from {list(AGENT_REGISTRY + EXTRA_AGENTS)}")
    try:
        return registry[name](seed=seed, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad options for agent {name!r} in {spec!r}: {exc}") from exc
