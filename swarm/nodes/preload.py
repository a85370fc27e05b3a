"""Imported once by the spawner's server (:mod:`formation_swarm.runtime.spawner`) before it
forks any role: the modules every agent and the world need, then frozen.

numpy's BLAS would start a thread per core on import; the server must not run
threads when it forks, so it is kept to the calling thread (the roles multiply
3x3 and 5x5 matrices: BLAS threads never help them). ``gc.freeze`` moves what
was imported out of the collector's reach, so that children do not touch (and
copy) those pages when they collect.
"""

import contextlib
import gc
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import formation_swarm.nodes.agent.main  # noqa: E402, F401
import formation_swarm.nodes.world.main  # noqa: E402, F401
from formation_swarm.agents.ekf import filter_class  # noqa: E402

filter_class()  # imports filterpy (and scipy.stats), which agents.ekf leaves to first use

with contextlib.suppress(ImportError):  # the children's command lines (formation_swarm.runtime.spawner)
    import setproctitle  # noqa: F401

gc.freeze()
