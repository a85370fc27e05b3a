"""Learning adapters over the engine (formation_swarm.Engine), in the
optional extra ``rl`` (``pip install 'formation-swarm[rl]'``): a PettingZoo
``ParallelEnv`` in which a policy drives chosen followers
(``formation_swarm.gym.pettingzoo_env``) and a Gymnasium ``Env`` for one
follower (``formation_swarm.gym.gymnasium_env``); the other robots fly their
laws. docs/learning.md has the spaces and the reward.

Importing this package imports neither PettingZoo nor Gymnasium; its
adapter modules do.
"""
