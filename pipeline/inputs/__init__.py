"""What the stages are given, on the floor every stage may import: several clips of one mesh and
their frame rules (:mod:`.clips`), and the built-in example sequences (:mod:`.examples`; the walker
turning on one foot, :mod:`.pivot_walker`)."""
