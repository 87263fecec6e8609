"""The contract every simulation engine keeps: the env's parameters, what a step reports, which engine does what.

* :mod:`.params` — :class:`~electroloc_gym.contract.params.EnvParams`, every env argument declared and validated once;
* :mod:`.observation` — the observation layouts, the info keys and the rules both engines share (flags, reward,
  the raw observation);
* :mod:`.motion` — how an action becomes the carriage's move and how the walls stop it;
* :mod:`.belief_summary` — the belief observation's scalars (declared as data) and the info's error and spread;
* :mod:`.capabilities` — for each engine, each env option: implemented, or refused with its reason;
* :mod:`.task_spec` — the declaration types of a task (its options, its per-env arrays);
* :mod:`.reset` — the options each env's ``reset`` takes and the first full reset, one check for both engines.

The engines (:mod:`electroloc_gym.engines`) read it; ``tests/test_engine_conformance.py`` checks that they keep it.
"""

__all__: list[str] = []
