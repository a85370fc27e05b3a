"""The shipped scenarios (TOML), installed with the package and found by name:
``swarm run fig11_obstacles`` or ``swarm scenarios`` to list them."""
