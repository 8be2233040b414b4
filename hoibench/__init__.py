"""hoibench: datasets, representations, evaluators, metrics and leaderboards for
text-driven 3D human-object interaction generation."""
__version__ = "0.6.0"

from .core.deprecated import install as _install_old_paths

_install_old_paths()
