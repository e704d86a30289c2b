"""Physics of the Cao & Tucker (2008) Cosserat rod, in pure UFL."""
