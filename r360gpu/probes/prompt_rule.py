"""The prompt rule of imported (and grounded) detections: which class names a prompt keeps.

The prompt is split at '.' into phrases (Grounding DINO's prompt syntax, e.g. ``"sofa."`` or
``"sofa. couch."``); the class name and each phrase are lower-cased, stripped and have inner
whitespace runs collapsed to one space; an annotation is kept when its class name equals one of the
phrases.  Substrings do not match ("sofa" does not keep "sofa cushion").  A prompt with no phrase
keeps every annotation, as the public converter (``scripts/convert_gsam2_to_masks.py``) does.
"""
from __future__ import annotations

import re

PROMPT_RULE = (
    "class_name equals one '.'-separated prompt phrase after lower-casing, stripping "
    "and collapsing whitespace; an empty prompt keeps all"
)


def _normalise(text: str) -> str:
    return re.sub(r"\s+", " ", text.strip().lower())


def prompt_phrases(prompt: str) -> list[str]:
    """Normalised phrases of a prompt (see the prompt rule in the module docstring)."""
    return [p for p in (_normalise(part) for part in prompt.split(".")) if p]


def label_matches(class_name: str, prompt: str) -> bool:
    """True when ``class_name`` is kept for ``prompt`` under the prompt rule."""
    phrases = prompt_phrases(prompt)
    return not phrases or _normalise(class_name) in phrases

