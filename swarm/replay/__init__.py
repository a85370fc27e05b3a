"""Replaying a robot from a run's wire recording (``swarm replay``).

``wire`` reads ``wire.mcap``; ``feed`` hands one robot's role what it took
in the run and collects its answers; ``compare`` sets them beside the
recorded commands; ``figure`` draws both wheel-speed series; ``cli`` is the
command. docs/replay.md says what is recorded and how to use it.
"""
