"""Expression mapping (paper §4-5): PCA parameter space, cardinal basis functions and better solvers."""
