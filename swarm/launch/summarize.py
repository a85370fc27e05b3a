"""A run's summary.json, from what its launcher saw: the parts its processes
wrote, the launcher's own events and rejections, how the run ended."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from formation_swarm.launch import external as external_mod
from formation_swarm.launch import ros2 as ros2_mod
from formation_swarm.launch.record import folder_gone
from formation_swarm.launch.result import Ending, end_reason, processes_part
from formation_swarm.runtime import summary as summary_mod

if TYPE_CHECKING:
    from formation_swarm.launch.launcher import Launch


def write(launch: Launch, code: int, ending: Ending) -> dict[str, Any]:
    """The summary of ``launch`` ended with ``code``, written to its folder;
    ``unkept`` in it says why it could not be (the folder gone, the disk full)."""
    run_dir = launch.run_dir
    parts = summary_mod.read_parts(run_dir / "stats")
    if launch.faults.rejections.total:  # fault calls refused: counted like every receiver's rejections
        parts["launcher"] = {"rejected": dict(launch.faults.rejections.by_reason)}
    world = launch.children.get("world")
    world_code = world.proc.returncode if world is not None and world.proc is not None else None
    events, last = launch.journal.events, launch.status.last
    reason, reached = end_reason(parts.get("world", {}), world_code, last, events, ending)
    options = launch.plan.options
    summary = summary_mod.build(
        run_id=launch.run_id,
        sc=launch.sc,
        mode=options.mode,
        parts=parts,
        exit_code=code,
        end_reason=reason,
        ended_at_s=reached,
        interrupted=ending.interrupted,
        timed_out=ending.timed_out,
        limit_s=ending.limit_s,
        processes=processes_part(launch.children, launch.hosts.lost),
        events=events,
        recording="recording.rrd" if options.logger else None,
    )
    launch.hosts.add_to_summary(summary)
    summary["ticks_seen"] = None if last is None else last.tick
    if launch.plan.external:
        external_mod.mark_summary(summary, launch.plan.external)
    if launch.plan.bridge:
        ros2_mod.mark_summary(summary, parts, launch.plan.ros2_robots)
    if (gone := folder_gone(run_dir, launch.folder_id)) is not None:
        summary["unkept"] = gone
        return summary
    try:
        summary_mod.write(run_dir, summary)
    except OSError as exc:
        summary["unkept"] = f"cannot write {exc.filename or run_dir / 'summary.json'}: {exc.strerror or exc}"
    return summary
