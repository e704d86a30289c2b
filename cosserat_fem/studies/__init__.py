"""Studies of many runs: sweeps, frequency responses, POD (Karhunen-Loeve)."""
