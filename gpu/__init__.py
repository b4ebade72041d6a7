"""skinsynth.gpu."""
