"""Analyses put together from the layers below: a time run (simulation), statics, modes, equilibria;
their observers, progress, budget and restart rules."""
