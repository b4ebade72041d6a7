"""skinsynth.pipeline."""
