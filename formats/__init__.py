"""skinsynth.formats."""
