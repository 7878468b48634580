"""Reading a JSON input file with errors that name the file."""
from __future__ import annotations

import json
import os
from pathlib import Path

from ..errors import InputError
from .paths import read_error


def read_json(path: str | os.PathLike):
    """The parsed JSON document in ``path``; InputError if unreadable or not valid JSON."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")  # a BOM (Windows editors) is not content
    except OSError as e:
        raise read_error(e, path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", path) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"invalid JSON: {e}", path) from None
