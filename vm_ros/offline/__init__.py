"""Running a model offline: the runner (OfflineRun) and its inputs (excitation files, input
series, built-in scenarios). It writes run logs through vm_ros.recording."""
