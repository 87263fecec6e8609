"""What is shown of a simulation: the belief agents read, the pictures people look at.

* :mod:`.belief` — :class:`~electroloc_gym.views.belief.BeliefView`, what an agent reads of the particle cloud;
* :mod:`.render` — matplotlib frames of an episode; :mod:`.eev_maps` — the EEV over carriage positions.
"""

__all__: list[str] = []
