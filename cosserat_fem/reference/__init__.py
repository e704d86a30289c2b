"""Independent closed-form references (pure numpy/scipy, no DOLFINx) for checking the rod solver."""
