"""Small helpers shared by every layer (no GPU, no metrics)."""
