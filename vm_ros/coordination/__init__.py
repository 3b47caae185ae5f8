"""Muscle coordination from motion: the drives whose forward run reproduces target joint
moments at least cost (docs/coordination.md).

- ``targets``: target joint moments of a motion (load_targets).
- ``problem``: the motion through a geometry, the targets at their frames (build_problem).
- ``forward``: forward runs of the full bank and their sensitivity to the drive nodes.
- ``costs``: the costs by name (COSTS).
- ``reserves``: reserve moments per coordinate and the frames beyond the muscles' capacity.
- ``solver``: the whole-trajectory iteration (solve).
- ``receding``: the receding-horizon coordinator of muscle_node's live coordination.
"""
