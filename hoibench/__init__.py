"""hoibench: datasets, representations, evaluators, metrics and leaderboards for
text-driven 3D human-object interaction generation."""
__version__ = "0.8.0"
