"""Stand-in torchvision for the parity scripts (see ../README.md)."""
__version__ = "0.29.0+standin"  # GroundingDINO parses the minor version
from . import ops, transforms  # noqa: E402,F401
