"""Batch and recursive identification mathematics (numpy/scipy, no Drake systems)."""
