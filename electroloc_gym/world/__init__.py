"""The world model: the tank, the carriage, the sensor, the targets and the other objects (paper §2–3, §6.5, §7).

* :mod:`.physics` — Eq. 4 and 7 (the perturbing dipole and the differential potential), pure functions;
* :mod:`.detection` — Eq. 5, 6 and Table 3's detection distances;
* :mod:`.apparatus` — the sphere, the water, the amplifier; :mod:`.conditions` — the 8 presets of Table 3;
* :mod:`.sensor` — the reading Φ (§3.1–3.2); :mod:`.sensor_array` — K pairs on the carriage (§7);
* :mod:`.scene` — mapped tanks (§6.5: superposed readings); :mod:`.distractors` — objects that are not the
  target, placed by :mod:`.distractor_layout` (geometry only).

What the robot *believes* about the reading is :mod:`electroloc_gym.sensor_models`; how N envs step is
:mod:`electroloc_gym.engines`.
"""

__all__: list[str] = []
