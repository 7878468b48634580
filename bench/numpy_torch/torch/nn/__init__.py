"""torch.nn: only ``functional`` (see ``torch/__init__.py``)."""
from . import functional  # noqa: F401
