"""Build-time importers of musculoskeletal geometry (OpenSim .osim, MuJoCo MJCF).

- ``common``: what both share: the imported muscle record, the rules that turn a source model's
  muscle parameters into a VM muscle-library entry (each with its source), the fibre-type table,
  writing the geometry file, the library and the summary into one output folder.
- ``osim``: ``vm-ros import-osim`` (needs the ``opensim`` extra, imported only there).
- ``motion``: reading OpenSim .mot/.sto motion files (NumPy only).

None of this is needed at run time: the node and the bank read only the files written here.
"""
