"""Per-view measurements of the Remove360 protocol (semantic, structural, geometric, fidelity)."""
