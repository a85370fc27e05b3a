"""The four figures of ``swarm report``, drawn with matplotlib from a run's
recording (``data.read_recording``) and summary: one module per family of
figures (maps: trajectories; timelines: formation error and V_N; estimates:
targets) over shared drawing (drawing), series (series) and the run's
context (context).

Choices a reader should know, also said on the figures themselves:

- Trajectories: formation snapshots at the formation events (a formation
  code changes) and in the middle of each stretch flown in one formation,
  each also drawn alone, zoomed, like the paper's Fig. 11 (a-d). A run with
  no formation change gets evenly timed snapshots on one panel.
- V_N: FIS-2's output changes every tick (it is what the controller used,
  unfiltered); drawn faint, with a 1 s centred moving average over it (for
  the eye only), and beside it the share of ticks at each V_N.
- Every time axis marks the formation switches (dotted, "-> line") and the
  faults (dashed instants, shaded windows). Limits are robust: a y axis goes
  to the 99.5th percentile with a margin, and says where a larger value was
  cut off.
- Titles name the scenario and the seed, and "cf. Fig. N" only when the run
  is a shipped scenario of the paper as shipped (any seed); under them, the
  leader's policy and the followers' laws (the summary's ``laws``).
- A line is not drawn across a gap in its series (an agent killed, frozen
  or restarted; a follower holding, which has no V_N), nor is a moving
  average taken across one.
- Beyond LEGEND_FOLLOWERS followers (a swarm), no figure lists every robot:
  the formation error and V_N draw each follower faint under their median
  and name the worst, the trajectories name the leader and the followers as
  one entry, and the targets figure shows the followers of largest error.
"""

from formation_swarm.report.figures.context import LEGEND_FOLLOWERS, Context, switches
from formation_swarm.report.figures.drawing import lane_rows
from formation_swarm.report.figures.estimates import targets
from formation_swarm.report.figures.maps import apart, equal_view, snapshot_times, trajectories
from formation_swarm.report.figures.series import gapped, moving_average, robust_top, stretches
from formation_swarm.report.figures.timelines import formation_error, vn

FIGURES = ("trajectories", "formation_error", "vn", "targets")  # their file stems, in the report's order

__all__ = [
    "FIGURES",
    "LEGEND_FOLLOWERS",
    "Context",
    "apart",
    "equal_view",
    "formation_error",
    "gapped",
    "lane_rows",
    "moving_average",
    "robust_top",
    "snapshot_times",
    "stretches",
    "switches",
    "targets",
    "trajectories",
    "vn",
]
