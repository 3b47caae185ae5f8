"""Reports of a run: summaries, tables and plots read from run logs, and whether a real-time run
is valid."""
