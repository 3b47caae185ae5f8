"""Benchmarks behind `vm-ros bench` (model, offline runs, muscle_node, OpenSim comparison)."""
