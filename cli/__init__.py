"""skinsynth.cli."""
