"""The shipped learned policies, one folder each (``models/NAME/``), installed as package data.

The benchmark finds them by name (``electroloc bench --agents ppo-belief``) through
:data:`MODELS_DIR`.
"""

from pathlib import Path

#: The folder holding the shipped model folders.
MODELS_DIR = Path(__file__).resolve().parent

__all__ = ["MODELS_DIR"]
