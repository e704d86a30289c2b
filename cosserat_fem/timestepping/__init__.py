"""Time integration: the integrators' tableaux and steps, the step-size controller, events and the
time loop. Knows nothing of rods."""
