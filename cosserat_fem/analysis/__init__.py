"""Analyses put together from the layers below: a time run (simulation), statics, modes, stability;
their observers, progress, budget and restart rules."""
