"""What is sampled on the mesh for the files (fields) and read back from a run folder (results). The
file formats themselves are in cosserat_fem.io."""
