"""Build-time importers of musculoskeletal geometry (OpenSim .osim, MuJoCo MJCF).

- ``common``: what both share: the imported muscle record, the rules that turn a source model's
  muscle parameters into a VM muscle-library entry (each with its source), the fibre-type table,
  writing the geometry file, the library and the summary into one output folder.
- ``pipeline``: the one import pipeline (sample, screen crossings, fit, flag, write) and the
  ``PathSource`` interface an importer implements: its exact paths, box and parameter mapping.
- ``osim``: ``vm-ros import-osim`` (OpenSim's paths: vm_ros.geometry.opensim_backend, needing the
  ``opensim`` extra); ``mjcf``: ``vm-ros import-mjcf`` (vm_ros.geometry.mujoco_backend).
- ``motion``: reading OpenSim .mot/.sto motion files (NumPy only).

None of this is needed at run time: the node and the bank read only the files written here.
"""
