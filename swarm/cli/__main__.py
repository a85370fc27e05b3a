"""``python -m formation_swarm.cli``: the ``swarm`` command."""

import sys

from formation_swarm.cli import main

sys.exit(main())
