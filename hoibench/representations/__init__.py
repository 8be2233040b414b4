"""Motion representations: ``hml263`` (HumanML3D), ``hoi269`` (HOI-Diff) and
``joint_level`` (ChainHOI), each with ``legacy`` and ``clean`` modes where they differ."""
from . import hml263, hoi269, joint_level, normalization  # noqa: F401
