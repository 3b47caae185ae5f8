"""Benchmarks behind `vm-ros bench` (vm_ros.bench.node_bench: muscle_node as a process)."""
