"""The built-in spectral renderer (numpy only): geometry of rays in a spherical-shell
atmosphere, a deterministic ray marcher with multiple scattering, a Monte Carlo
reference, cameras and image output."""
